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
use photopose::estimator::verify::texture::{Brightness, Scratch};
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

impl Fixture {
    /// The example frame as the camera sends it in `format`.
    fn frame(&self, format: PixelFormat) -> SbsBytes<'_> {
        let (w, h) = self.images.eye_size();
        let bytes = match format {
            PixelFormat::Rgb8 => &self.sbs,
            PixelFormat::Yuyv => &self.yuyv,
        };
        SbsBytes {
            bytes,
            width: w as usize,
            height: h as usize,
            row_stride: 2 * w as usize * format.bytes_per_pixel(),
            format,
        }
    }
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
    let frame = f.frame(format);
    let (w, h) = (frame.width, frame.height);
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

/// The texture terms (stereo and structure) on random visible individuals at full
/// resolution, on the one-shot search's texture points (every fourth model point).
#[divan::bench]
fn texture_terms(bencher: Bencher) {
    let f = fixture();
    let p = &f.prepared;
    let problem = p.problem(&f.config);
    let points = &p.texture_points[0];
    let poses: Vec<_> = f.genes.iter().map(|g| p.bounds.decode(g)).collect();
    bencher
        .counter(ItemsCount::new(poses.len() * points.inner_v.len()))
        .bench_local(|| {
            poses
                .iter()
                .map(|c| problem.texture_at(0, points, black_box(c)).sum())
                .sum::<f64>()
        });
}

/// A tracking frame's brightness read: one eye's brightness and detail in a 400 × 300
/// region around the card, into buffers kept from frame to frame.
#[divan::bench]
fn brightness_region(bencher: Bencher) {
    let f = fixture();
    let frame = f.frame(PixelFormat::Rgb8);
    let region = Region {
        cols: 440..840,
        rows: 210..510,
    };
    let (mut eye, mut scratch) = (Brightness::empty(), Scratch::default());
    bencher
        .counter(ItemsCount::new(region.cols.len() * region.rows.len()))
        .bench_local(|| eye.refill_region(black_box(&frame), 0, &region, &mut scratch));
}
