//! `cargo bench`: the fitness kernel and the per-frame colour preparation on the example
//! HD frame (`tests/data/examples/`), with the built-in configuration.
//!
//! Throughput is in sample-point evaluations (kernel: N_in + N_out points × 2 images per
//! individual) or in pixels (colour preparation).

// Test code: a failed unwrap is a failed test.
#![allow(clippy::unwrap_used)]

#[path = "../tests/common/mod.rs"]
mod common;

use std::sync::OnceLock;

use divan::counter::ItemsCount;
use divan::{black_box, Bencher};
use photopose::config::Config;
use photopose::estimator::fitness::Fitness;
use photopose::estimator::ga::robust::view_sample;
use photopose::estimator::ga::{Genes, Problem};
use photopose::estimator::model::PhotoModel;
use photopose::estimator::oneshot::Prepared;
use photopose::vision::frame::{Region, StereoImages};
use photopose::vision::lookup::{LevelLookup, LookupImage, SbsBytes};
use photopose::vision::PixelFormat;
use rand::rngs::StdRng;
use rand::SeedableRng;

const FRAME: &str = "examples/rocket-frame.jpg";
const MODEL: &str = "examples/rocket.model";
/// Random individuals per kernel iteration.
const INDIVIDUALS: usize = 2000;

fn main() {
    divan::main();
}

struct Fixture {
    config: Config,
    images: StereoImages,
    sbs: Vec<u8>,
    yuyv: Vec<u8>,
    prepared: Prepared,
    genes: Vec<Genes>,
}

fn fixture() -> &'static Fixture {
    static FIXTURE: OnceLock<Fixture> = OnceLock::new();
    FIXTURE.get_or_init(|| {
        let config = Config::load(None).expect("built-in configuration");
        let model = PhotoModel::load(&common::data(MODEL)).expect("example model");
        let images = StereoImages::load_sbs(&common::data(FRAME)).expect("example frame");
        let prepared = Prepared::new(&model, &images, &config).expect("example calibration");
        let one = Problem::new(&prepared.scorer, &prepared.levels, &prepared.points, prepared.bounds, 1);
        let mut rng = StdRng::seed_from_u64(1);
        let genes = (0..INDIVIDUALS).map(|_| view_sample(&one, &mut rng)).collect();
        let sbs = images.to_sbs().into_raw();
        let yuyv = photopose::vision::color::yuyv_from_rgb(&sbs, images.eye_size().0 as usize);
        Fixture {
            config,
            images,
            sbs,
            yuyv,
            prepared,
            genes,
        }
    })
}

/// The kernel on random visible individuals at full resolution, one thread and all cores.
#[divan::bench(args = [1, 0])]
fn kernel(bencher: Bencher, threads: usize) {
    let f = fixture();
    let p = &f.prepared;
    let problem = Problem::new(&p.scorer, &p.levels, &p.points, p.bounds, threads);
    let points = f.genes.len() * 2 * p.points[0].len();
    let mut out = vec![Fitness::default(); f.genes.len()];
    bencher
        .counter(ItemsCount::new(points))
        .bench_local(|| problem.evaluate_batch(0, black_box(&f.genes), &mut out));
}

/// Tracking's colour preparation: one whole HD eye converted from the frame's RGB8
/// (synthetic camera) or YUYV (ZED) rows into its lookup image (a tracking frame
/// converts only regions of interest).
#[divan::bench(args = [PixelFormat::Rgb8, PixelFormat::Yuyv])]
fn colour_prep_eye(bencher: Bencher, format: PixelFormat) {
    let f = fixture();
    let (w, h) = f.images.eye_size();
    let (w, h) = (w as usize, h as usize);
    let bytes = match format {
        PixelFormat::Rgb8 => &f.sbs,
        PixelFormat::Yuyv => &f.yuyv,
    };
    let frame = SbsBytes {
        bytes,
        width: w,
        height: h,
        row_stride: 2 * w * format.bytes_per_pixel(),
        format,
    };
    let rule = f.prepared.scorer.texel_rule();
    let mut image = LookupImage::with_capacity(w, h);
    let all = Region::all(w, h);
    bencher
        .counter(ItemsCount::new(w * h))
        .bench_local(|| image.refill(black_box(&frame), 0, &all, &rule));
}

/// A one-shot estimate's colour preparation: the lookup pyramid of both eyes.
#[divan::bench]
fn colour_prep_pyramid(bencher: Bencher) {
    let f = fixture();
    let (w, h) = f.images.eye_size();
    let rig = f.config.calibration.rig_for_image(w, h).expect("HD calibration");
    let rule = f.prepared.scorer.texel_rule();
    let levels = f.config.robust.pyramid_levels;
    bencher
        .counter(ItemsCount::new(2 * w as usize * h as usize))
        .bench_local(|| LevelLookup::pyramid(black_box(&f.images), &rig, levels, &rule));
}
