//! `photopose bench`: how fast the estimator is on this machine. The fitness kernel on
//! one frame (one thread and all), a one-shot estimate (the configured generations), and the
//! per-frame time of the tracking loop on a synthetic HD sequence.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{anyhow, Result};
use rand::rngs::StdRng;
use rand::SeedableRng;
use serde::Serialize;

use crate::capture::synthetic::SyntheticSource;
use crate::capture::{FrameSource, DEFAULT_SCENE};
use crate::cli::report::stats::Samples;
use crate::config::Config;
use crate::estimator::fitness::Fitness;
use crate::estimator::ga::robust::view_sample;
use crate::estimator::ga::{Genes, Problem};
use crate::estimator::model::PhotoModel;
use crate::estimator::oneshot::{self, Prepared};
use crate::estimator::tracking::StreamTracker;
use crate::render::SceneSpec;
use crate::vision::frame::StereoImages;
use crate::vision::lookup::SbsBytes;

/// Measure the fitness kernel, a one-shot estimate and the tracking loop.
#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// Side-by-side frame the kernel and the one-shot estimate run on.
    #[arg(long, value_name = "FRAME.png")]
    pub sbs: PathBuf,
    /// Photo-model matching that frame.
    #[arg(long, value_name = "MODEL")]
    pub model: PathBuf,
    /// Configuration file; built-in defaults otherwise.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Individuals evaluated for the kernel figures.
    #[arg(long, default_value_t = 20_000)]
    pub individuals: usize,
    /// Threads of the multi-threaded run (0: one per core).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Frames of the synthetic sequence for the tracking figures.
    #[arg(long, default_value_t = 300)]
    pub frames: usize,
    /// Scene of the synthetic sequence (its photo becomes the tracked model).
    #[arg(long, value_name = "SCENE.toml", default_value = DEFAULT_SCENE)]
    pub scene: PathBuf,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

/// What `--json` prints.
#[derive(Debug, Serialize)]
struct Report {
    threads: usize,
    points_per_individual: usize,
    individuals_per_s_1t: f64,
    points_per_s_1t: f64,
    ns_per_point_1t: f64,
    individuals_per_s_all: f64,
    points_per_s_all: f64,
    ns_per_point_all: f64,
    oneshot_generations: usize,
    oneshot_s: f64,
    tracking_frames: usize,
    tracking_acquisition_s: f64,
    tracking_relocation_ms: f64,
    tracking_frame_p50_ms: f64,
    tracking_frame_p99_ms: f64,
    tracking_frame_max_ms: f64,
}

/// Runs the three measurements, printing each as it is done (or one JSON object).
pub fn run(args: &BenchArgs) -> Result<()> {
    if args.individuals == 0 || args.frames < 3 {
        return Err(anyhow!("--individuals must be ≥ 1 and --frames ≥ 3"));
    }
    let config = Config::load(args.config.as_deref())?;
    let model = PhotoModel::load(&args.model)?;
    let images = StereoImages::load_sbs(&args.sbs)?;
    let say = |line: String| {
        if !args.json {
            println!("{line}");
        }
    };
    let kernel = kernel(args, &config, &model, &images, &say)?;

    // One-shot estimate as `estimate` runs it (the configured generations), frame
    // preparation included.
    let generations = config.ga.generations;
    let start = Instant::now();
    let outcome = oneshot::run(&model, &images, &config, generations, config.ga.seed, &mut |_| {})?;
    let oneshot = start.elapsed().as_secs_f64();
    say(format!(
        "one-shot estimate, {generations} generations ({:?} mode): {oneshot:.3} s ({} evaluations, F {:.3})",
        config.ga.mode, outcome.evaluations, outcome.fitness.f
    ));

    let (acquisition, relocation, frames) = tracking(args, &config)?;
    say(format!(
        "tracking {} (HD 60 fps, up to 150 mm/s), {} frames: acquisition {acquisition:.2} s, relocation {relocation:.0} ms, then per frame p50 {:.2} ms, p99 {:.2} ms, max {:.2} ms",
        args.scene.display(),
        args.frames,
        frames.median(),
        frames.percentile(99.0),
        frames.max()
    ));
    if args.json {
        let report = Report {
            threads: kernel.threads,
            points_per_individual: kernel.per_individual,
            individuals_per_s_1t: kernel.one.individuals_per_s,
            points_per_s_1t: kernel.one.points_per_s,
            ns_per_point_1t: kernel.one.ns_per_point,
            individuals_per_s_all: kernel.all.individuals_per_s,
            points_per_s_all: kernel.all.points_per_s,
            ns_per_point_all: kernel.all.ns_per_point,
            oneshot_generations: generations,
            oneshot_s: oneshot,
            tracking_frames: args.frames,
            tracking_acquisition_s: acquisition,
            tracking_relocation_ms: relocation,
            tracking_frame_p50_ms: frames.median(),
            tracking_frame_p99_ms: frames.percentile(99.0),
            tracking_frame_max_ms: frames.max(),
        };
        println!("{}", serde_json::to_string(&report)?);
    }
    Ok(())
}

/// Throughput of the fitness kernel on one thread or several.
#[derive(Debug, Clone, Copy)]
struct Throughput {
    individuals_per_s: f64,
    points_per_s: f64,
    ns_per_point: f64,
}

/// The kernel's figures: one thread, `threads` threads.
struct KernelFigures {
    threads: usize,
    per_individual: usize,
    one: Throughput,
    all: Throughput,
}

/// Times the fitness kernel on `--individuals` candidates the cameras can see (random
/// pixel, depth, size, tilt), on one thread and on all.
fn kernel(
    args: &BenchArgs,
    config: &Config,
    model: &PhotoModel,
    images: &StereoImages,
    say: &dyn Fn(String),
) -> Result<KernelFigures> {
    let prepared = Prepared::new(model, images, config)?;
    let points = prepared.points[0].len();
    let per_individual = 2 * points;
    let one = Problem::new(&prepared.scorer, &prepared.levels, &prepared.points, prepared.bounds, 1);
    let mut rng = StdRng::seed_from_u64(config.ga.seed);
    let genes: Vec<Genes> = (0..args.individuals).map(|_| view_sample(&one, &mut rng)).collect();
    let all = Problem::new(
        &prepared.scorer,
        &prepared.levels,
        &prepared.points,
        prepared.bounds,
        args.threads,
    );
    let threads = all.workers.threads();
    say(format!(
        "fitness on {} ({} points: {per_individual} point evaluations per individual, both images)",
        args.sbs.display(),
        points
    ));
    let [one, all] = [&one, &all].map(|problem| {
        let mut out = vec![Fitness::default(); genes.len()];
        problem.evaluate_batch(0, &genes, &mut out); // warm-up: caches, thread pool
        let start = Instant::now();
        problem.evaluate_batch(0, &genes, &mut out);
        let s = start.elapsed().as_secs_f64();
        let evaluated = (genes.len() * per_individual) as f64;
        Throughput {
            individuals_per_s: genes.len() as f64 / s,
            points_per_s: evaluated / s,
            ns_per_point: s * 1e9 / evaluated,
        }
    });
    for (t, name) in [(one, "1 thread ".to_string()), (all, format!("{threads} threads"))] {
        say(format!(
            "  {name}: {:>8.0} individuals/s, {:>6.1} M point evaluations/s, {:.2} ns per point",
            t.individuals_per_s,
            t.points_per_s * 1e-6,
            t.ns_per_point
        ));
    }
    Ok(KernelFigures {
        threads,
        per_individual,
        one,
        all,
    })
}

/// Tracks `--frames` frames of the synthetic camera on `--scene`, rendering excluded:
/// the acquisition (first frame), s, the relocation (second frame), ms, and each later
/// frame's time, ms.
fn tracking(args: &BenchArgs, config: &Config) -> Result<(f64, f64, Samples)> {
    let spec = SceneSpec::load(&args.scene)?;
    let tracked = super::scene_model(&spec, config)?;
    let mut source = SyntheticSource::open(&args.scene, config, 60.0, 150.0)?;
    let geometry = source.geometry();
    let mut buf = vec![0u8; geometry.frame_len()];
    let mut tracker = StreamTracker::new(tracked, config.clone());
    let mut times = Vec::with_capacity(args.frames);
    let (mut acquisition, mut relocation) = (0.0, 0.0);
    for i in 0..args.frames {
        source.fill(&mut buf)?;
        let frame = SbsBytes {
            bytes: &buf,
            width: geometry.width as usize,
            height: geometry.height as usize,
            row_stride: geometry.row_stride(),
            format: geometry.format,
        };
        let start = Instant::now();
        tracker.prepare(&frame)?;
        tracker.step();
        let s = start.elapsed().as_secs_f64();
        match i {
            0 => acquisition = s,
            1 => relocation = s * 1e3,
            _ => times.push(s * 1e3),
        }
    }
    Ok((acquisition, relocation, Samples::new(times)))
}
