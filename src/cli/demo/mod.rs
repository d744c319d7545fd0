//! `photopose demo`: the whole service on the synthetic camera. It builds the photo-model
//! of the scene's photo, starts `capture` (a card moving along a loop), `estimator` and
//! `controller` as three processes, watches `photopose/poses` against
//! `photopose/truth` with a live status line, then stops them and prints a summary and
//! writes a plot of the true and estimated trajectories. With `--rerun FILE.rrd` a fourth
//! process, `photopose viewer`, records the run.

mod processes;
mod run;

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{anyhow, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};

use crate::capture::scenario::film::Film;
use crate::capture::scenario::{InView, Scenario};
use crate::capture::DEFAULT_SCENE;
use crate::cli::report::plot;
use crate::config::Config;
use crate::render::SceneSpec;
use crate::transport::ipc::{receive_poses, Ipc, PoseSubscriber};
use crate::transport::messages::{monotonic_ns, ObjectName, POSES_SERVICE, TRUTH_SERVICE};
use processes::Processes;
use run::Run;

/// Run capture, estimator and controller together on the synthetic camera.
#[derive(clap::Args, Debug)]
pub struct DemoArgs {
    /// How long to run, seconds.
    #[arg(long, default_value_t = 20.0)]
    pub seconds: f64,
    /// Scene of the synthetic camera (its photo becomes the photo-model); default
    /// `config/scenes/rocket.toml`, with `--objects 2` `config/scenes/pair.toml`.
    #[arg(long, value_name = "SCENE.toml")]
    pub scene: Option<PathBuf>,
    /// Peak speed of the card, mm/s.
    #[arg(long, default_value_t = 150.0)]
    pub speed: f64,
    /// Camera frame rate: 60, or the scenario's own.
    #[arg(long)]
    pub fps: Option<f64>,
    /// Play a scenario instead of the loop, over and over: sweep, sweep-60fps, yuyv,
    /// light, occlude, leave or approach (docs/tracking-sequences.md). It is rendered
    /// first, then played by `capture --source replay:DIR --loop`; the live status and
    /// the summary give the success rate against the truth.
    #[arg(long, value_name = "NAME", conflicts_with_all = ["scene", "speed", "objects"])]
    pub scenario: Option<String>,
    /// Play the scenario once, as a recorded sequence is played (`capture --source
    /// replay:DIR` without `--loop`), and stop when it ends (or after `--seconds`): the
    /// success of one pass, as the held-out sequences are scored.
    #[arg(long, requires = "scenario")]
    pub once: bool,
    /// Where to write the trajectory plot.
    #[arg(long, value_name = "FILE.png", default_value = "demo-trajectory.png")]
    pub plot: PathBuf,
    /// Configuration file passed to every process; built-in defaults otherwise.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Also run `photopose viewer` and record the run into this Rerun file (feature
    /// `rerun`).
    #[arg(long, value_name = "FILE.rrd")]
    pub rerun: Option<PathBuf>,
    /// Cards to track at once: 1, or 2 (a second card, `config/scenes/hopper-beside.toml`,
    /// moves on a loop of its own beside the first, each tracked by its own population).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u8).range(1..=2))]
    pub objects: u8,
}

/// The camera's frame rate without `--fps`.
pub const DEFAULT_FPS: f64 = 60.0;
/// The second card of `--objects 2`.
pub const SECOND_CARD: &str = "config/scenes/hopper-beside.toml";
/// The default first card and wall of `--objects 2`: room for the second card beside it.
pub const PAIR_SCENE: &str = "config/scenes/pair.toml";

/// Runs the demo: the photo-model, the three processes, the live status, then the
/// summary and the trajectory plot.
pub fn run(args: &DemoArgs) -> Result<()> {
    if !(args.seconds.is_finite() && args.seconds > 0.0) {
        return Err(anyhow!("--seconds {} must be a positive number", args.seconds));
    }
    if let Some(fps) = args.fps.filter(|f| !(f.is_finite() && *f > 0.0)) {
        return Err(anyhow!("--fps {fps} must be a positive number"));
    }
    if args.rerun.is_some() && !cfg!(feature = "rerun") {
        return Err(crate::viewer::unavailable("--rerun"));
    }
    let config = Config::load(args.config.as_deref())?;
    let mut stage = Stage::default();
    let shown = stage.set(args, &config).and_then(|()| show(args, &stage));
    stage.clean_up();
    let run = shown?;
    println!("{}", run.summary());
    plot::save(&run.plot()?, &args.plot)?;
    println!("trajectory plot: {}", args.plot.display());
    Ok(())
}

/// What the demo plays: the models of the cards, the capture's source arguments, and
/// for a scenario each frame's share of the card in view; files to remove at the end.
#[derive(Default)]
struct Stage {
    models: Vec<(ObjectName, PathBuf)>,
    capture: Vec<String>,
    title: String,
    visible: Option<Vec<InView>>,
    scratch: Vec<PathBuf>,
}

impl Stage {
    /// Builds the models and the source: a scenario rendered into a scratch directory,
    /// or the synthetic camera's scene files. What it wrote is removed by
    /// [`Stage::clean_up`], also when it fails.
    fn set(&mut self, args: &DemoArgs, config: &Config) -> Result<()> {
        let pid = std::process::id();
        let stage = self;
        if let Some(name) = &args.scenario {
            let scenario = Scenario::named(name).map_err(anyhow::Error::msg)?;
            let dir = std::env::temp_dir().join(format!("photopose-demo-{pid}-{name}"));
            let model = std::env::temp_dir().join(format!("photopose-demo-{pid}-0.model"));
            stage.scratch = vec![dir.clone(), model.clone()];
            Film::model(&scenario, Path::new("."), config)
                .map_err(anyhow::Error::msg)?
                .save(&model)?;
            let stem = Path::new(scenario.card.photo).file_stem().map(|s| s.to_string_lossy());
            stage
                .models
                .push((ObjectName::from_stem(&stem.unwrap_or_default()), model));
            stage.visible = Some(super::render::record_scenario(&scenario, &dir, config)?);
            let fps = args.fps.unwrap_or(scenario.fps).to_string();
            let source = format!("replay:{}", dir.display());
            stage.capture = ["--source", &source, "--fps", &fps].map(String::from).to_vec();
            if !args.once {
                stage.capture.push("--loop".into());
            }
            let played = if args.once { "once" } else { "looped" };
            stage.title = format!("scenario {name} ({} s, {played}) at {fps} fps", scenario.seconds);
            return Ok(());
        }
        for (k, scene) in args.cards().iter().enumerate() {
            let spec = SceneSpec::load(scene)?;
            let stem = spec.photo.file_stem().map(|s| s.to_string_lossy()).unwrap_or_default();
            let path = std::env::temp_dir().join(format!("photopose-demo-{pid}-{k}.model"));
            stage.scratch.push(path.clone());
            super::scene_model(&spec, config)?.save(&path)?;
            stage.models.push((ObjectName::from_stem(&stem), path));
        }
        let fps = args.fps.unwrap_or(DEFAULT_FPS).to_string();
        let scene = format!("synthetic:{}", args.scene().display());
        let speed = args.speed.to_string();
        stage.capture = ["--source", &scene, "--speed", &speed, "--fps", &fps]
            .map(String::from)
            .to_vec();
        for card in &args.cards()[1..] {
            stage.capture.extend(["--card".into(), card.display().to_string()]);
        }
        stage.title = format!("{} at up to {} mm/s, {fps} fps", args.scene().display(), args.speed);
        Ok(())
    }

    /// Removes the models and the rendered scenario.
    fn clean_up(&self) {
        for path in &self.scratch {
            let _ = std::fs::remove_dir_all(path).or_else(|_| std::fs::remove_file(path));
        }
    }
}

/// Starts the processes, watches them for `--seconds`, and stops them.
fn show(args: &DemoArgs, stage: &Stage) -> Result<Run> {
    let ipc = Ipc::new("photopose-demo")?;
    let poses = ipc.pose_subscriber(POSES_SERVICE)?;
    let truths = ipc.pose_subscriber(TRUTH_SERVICE)?;
    let (mut procs, controller) = start_processes(args, stage)?;
    let span = if args.once { "until it ends, at most" } else { "for" };
    println!(
        "photopose demo: {} {span} {} s (Ctrl-C stops early)",
        stage.title, args.seconds
    );
    let names: Vec<String> = stage.models.iter().map(|(n, _)| n.to_string()).collect();
    let mut run = Run::new(&names, stage.visible.clone());
    let watched = watch(
        args.seconds,
        args.once,
        &ipc,
        [&poses, &truths],
        &mut procs,
        controller.as_deref(),
        &mut run,
    );
    procs.stop();
    watched.map(|()| run)
}

impl DemoArgs {
    /// The scene of the first card and the wall.
    fn scene(&self) -> PathBuf {
        let default = if self.objects >= 2 { PAIR_SCENE } else { DEFAULT_SCENE };
        self.scene.clone().unwrap_or_else(|| PathBuf::from(default))
    }

    /// The scene files of the cards: `--scene`, then the second card's.
    fn cards(&self) -> Vec<PathBuf> {
        let mut cards = vec![self.scene()];
        if self.objects >= 2 {
            cards.push(PathBuf::from(SECOND_CARD));
        }
        cards
    }
}

/// Starts `estimator` (on the named models), `capture` (the synthetic camera) and
/// `controller`, each stopping by itself 10 s after the demo should have; returns them
/// and the slot holding the controller's last line.
fn start_processes(args: &DemoArgs, stage: &Stage) -> Result<(Processes, Option<Arc<Mutex<String>>>)> {
    let models = &stage.models;
    let exe = std::env::current_exe().context("cannot find the photopose executable")?;
    // The children also stop by themselves, should the demo be killed.
    let limit = format!("{}", args.seconds + 10.0);
    let mut common: Vec<String> = Vec::new();
    if let Some(c) = &args.config {
        common.extend(["--config".into(), c.display().to_string()]);
    }
    let mut procs = Processes::default();
    let model = models[0].1.display().to_string();
    let named: Vec<String> = models
        .iter()
        .flat_map(|(name, path)| ["--model".into(), format!("{name}={}", path.display())])
        .collect();
    let named: Vec<&str> = named.iter().map(String::as_str).collect();
    procs.spawn(&exe, "estimator", &[&named, &["--seconds", &limit]], &common, false)?;
    if let Some(rrd) = &args.rerun {
        let rrd = rrd.display().to_string();
        let viewer: &[&str] = &["--save", &rrd, "--model", &model, "--seconds", &limit];
        procs.spawn(&exe, "viewer", &[viewer], &common, false)?;
    }
    let capture: Vec<&str> = stage.capture.iter().map(String::as_str).collect();
    procs.spawn(&exe, "capture", &[&capture, &["--seconds", &limit]], &common, false)?;
    let controller = procs.spawn(&exe, "controller", &[&["--seconds", &limit]], &common, true)?;
    Ok((procs, controller))
}

/// Collects truths and poses for `seconds` (or until a stop is requested), showing the
/// status line; fails when a child process exits early, except a capture that played a
/// sequence `once` to its end: then the poses of its last frames are collected for
/// [`DRAIN`] more.
fn watch(
    seconds: f64,
    once: bool,
    ipc: &Ipc,
    [poses, truths]: [&PoseSubscriber; 2],
    procs: &mut Processes,
    controller: Option<&Mutex<String>>,
    run: &mut Run,
) -> Result<()> {
    let start = Instant::now();
    let bar = status_bar();
    let every = Duration::from_millis(if bar.is_hidden() { 2000 } else { 250 });
    let mut shown = Instant::now();
    let mut ended: Option<Instant> = None;
    while ipc.wait(Duration::from_millis(1))
        && start.elapsed().as_secs_f64() < seconds
        && ended.is_none_or(|t| t.elapsed() < DRAIN)
    {
        let now = monotonic_ns();
        while let Some(set) = receive_poses(truths)? {
            run.truth(&set);
        }
        while let Some(set) = receive_poses(poses)? {
            run.poses(&set, now);
        }
        match procs.exited() {
            Some((name, status)) if once && name == "capture" && status.success() => {
                ended.get_or_insert_with(Instant::now);
            }
            Some((name, status)) => {
                bar.finish_and_clear();
                return Err(anyhow!("photopose {name} stopped ({status}); see its message above"));
            }
            None => {}
        }
        if shown.elapsed() >= every {
            shown = Instant::now();
            let line = run.status(start.elapsed().as_secs_f64());
            if bar.is_hidden() {
                eprintln!("{line}");
            } else {
                let controller = controller.map(|l| l.lock().map(|s| s.clone()).unwrap_or_default());
                bar.set_message(format!("{line}\ncontroller: {}", controller.unwrap_or_default()));
            }
        }
    }
    bar.finish();
    Ok(())
}

/// How long poses are still collected after a sequence played `once` has ended: the
/// estimator's last frames, and a search still running when it ended.
const DRAIN: Duration = Duration::from_millis(1500);

/// The live status on a terminal: two lines (the figures, the controller's last
/// line) redrawn in place. Hidden when stderr is not a terminal (logs, CI, pipes),
/// where the status is printed as plain lines every 2 s instead.
fn status_bar() -> ProgressBar {
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new_spinner();
    if let Ok(style) = ProgressStyle::with_template("{msg}") {
        bar.set_style(style);
    }
    bar
}
