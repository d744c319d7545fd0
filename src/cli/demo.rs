//! `photopose demo`: the whole service on the synthetic camera. It builds the photo-model
//! of the scene's photo, starts `capture` (a card moving along a loop), `estimator` and
//! `controller` as three processes, watches `photopose/poses` against
//! `photopose/truth` with a live status line, then stops them and prints a summary and
//! writes a plot of the true and estimated trajectories. With `--rerun FILE.rrd` a fourth
//! process, `photopose viewer`, records the run.

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, IsTerminal};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{anyhow, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};

use crate::capture::DEFAULT_SCENE;
use crate::cli::report::plot::{self, Panel, Series, PALETTE};
use crate::cli::report::stats::Samples;
use crate::config::Config;
use crate::render::SceneSpec;
use crate::transport::ipc::{receive_poses, Ipc, PoseSubscriber};
use crate::transport::messages::{monotonic_ns, ObjectName, PoseMsg, PoseSet, Status, POSES_SERVICE, TRUTH_SERVICE};

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
    /// Camera frame rate.
    #[arg(long, default_value_t = 60.0)]
    pub fps: f64,
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
    if args.rerun.is_some() && !cfg!(feature = "rerun") {
        return Err(crate::viewer::unavailable("--rerun"));
    }
    let config = Config::load(args.config.as_deref())?;
    let cards = args.cards();
    let mut models = Vec::new();
    for (k, scene) in cards.iter().enumerate() {
        let spec = SceneSpec::load(scene)?;
        let stem = spec.photo.file_stem().map(|s| s.to_string_lossy()).unwrap_or_default();
        let name = ObjectName::from_stem(&stem);
        let path = std::env::temp_dir().join(format!("photopose-demo-{}-{k}.model", std::process::id()));
        super::scene_model(&spec, &config)?.save(&path)?;
        models.push((name, path));
    }
    let ipc = Ipc::new("photopose-demo")?;
    let poses = ipc.pose_subscriber(POSES_SERVICE)?;
    let truths = ipc.pose_subscriber(TRUTH_SERVICE)?;
    let (mut procs, controller) = start_processes(args, &models)?;
    println!(
        "photopose demo: {} at up to {} mm/s, {} fps, for {} s (Ctrl-C stops early)",
        args.scene().display(),
        args.speed,
        args.fps,
        args.seconds
    );
    let names: Vec<String> = models.iter().map(|(n, _)| n.to_string()).collect();
    let watched = watch(
        args.seconds,
        &ipc,
        [&poses, &truths],
        &mut procs,
        controller.as_deref(),
        &names,
    );
    procs.stop();
    drop((poses, truths));
    for (_, path) in &models {
        let _ = std::fs::remove_file(path);
    }
    let run = watched?;
    println!("{}", run.summary());
    plot::save(&run.plot()?, &args.plot)?;
    println!("trajectory plot: {}", args.plot.display());
    Ok(())
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
fn start_processes(
    args: &DemoArgs,
    models: &[(ObjectName, PathBuf)],
) -> Result<(Processes, Option<Arc<Mutex<String>>>)> {
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
    let scene = format!("synthetic:{}", args.scene().display());
    let (speed, fps) = (args.speed.to_string(), args.fps.to_string());
    let capture: &[&str] = &[
        "--source",
        &scene,
        "--speed",
        &speed,
        "--fps",
        &fps,
        "--seconds",
        &limit,
    ];
    let more: Vec<String> = args.cards()[1..]
        .iter()
        .flat_map(|c| ["--card".into(), c.display().to_string()])
        .collect();
    let more: Vec<&str> = more.iter().map(String::as_str).collect();
    procs.spawn(&exe, "capture", &[capture, &more], &common, false)?;
    let controller = procs.spawn(&exe, "controller", &[&["--seconds", &limit]], &common, true)?;
    Ok((procs, controller))
}

/// Collects truths and poses for `seconds` (or until a stop is requested), showing the
/// status line; fails when a child process exits early.
fn watch(
    seconds: f64,
    ipc: &Ipc,
    [poses, truths]: [&PoseSubscriber; 2],
    procs: &mut Processes,
    controller: Option<&Mutex<String>>,
    names: &[String],
) -> Result<Run> {
    let mut run = Run::new(names);
    let start = Instant::now();
    let bar = status_bar();
    let every = Duration::from_millis(if bar.is_hidden() { 2000 } else { 250 });
    let mut shown = Instant::now();
    while ipc.wait(Duration::from_millis(1)) && start.elapsed().as_secs_f64() < seconds {
        let now = monotonic_ns();
        while let Some(set) = receive_poses(truths)? {
            run.truth(&set);
        }
        while let Some(set) = receive_poses(poses)? {
            run.poses(&set, now);
        }
        if let Some(line) = procs.exited() {
            bar.finish_and_clear();
            return Err(anyhow!("{line}; see its message above"));
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
    Ok(run)
}

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

/// The child processes, stopped (SIGTERM, then SIGKILL) when dropped.
#[derive(Default)]
struct Processes {
    children: Vec<(String, Child)>,
}

impl Processes {
    /// Starts `photopose <command> <args…> <common…>`; with `watch`, its last stdout line
    /// is kept in the returned slot.
    fn spawn(
        &mut self,
        exe: &Path,
        command: &str,
        args: &[&[&str]],
        common: &[String],
        watch: bool,
    ) -> Result<Option<Arc<Mutex<String>>>> {
        let mut cmd = Command::new(exe);
        cmd.arg(command).args(args.iter().flat_map(|a| a.iter())).args(common);
        if std::env::var_os("RUST_LOG").is_none() {
            cmd.env("RUST_LOG", "warn");
        }
        cmd.stdin(Stdio::null())
            .stdout(if watch { Stdio::piped() } else { Stdio::null() });
        let mut child = cmd
            .spawn()
            .with_context(|| format!("cannot start photopose {command}"))?;
        let slot = match child.stdout.take() {
            Some(out) => {
                let slot = Arc::new(Mutex::new(String::new()));
                let writer = slot.clone();
                std::thread::Builder::new()
                    .name(format!("photopose-demo-{command}"))
                    .spawn(move || {
                        for line in BufReader::new(out).lines().map_while(Result::ok) {
                            if let Ok(mut s) = writer.lock() {
                                *s = line;
                            }
                        }
                    })
                    .context("cannot start a reader thread")?;
                Some(slot)
            }
            None => None,
        };
        self.children.push((command.to_string(), child));
        Ok(slot)
    }

    /// A line naming a child that has exited, if any.
    fn exited(&mut self) -> Option<String> {
        self.children.iter_mut().find_map(|(name, c)| match c.try_wait() {
            Ok(Some(status)) => Some(format!("photopose {name} stopped ({status})")),
            _ => None,
        })
    }

    /// Asks every child to terminate, waits up to 3 s, then kills what is left.
    fn stop(&mut self) {
        for (_, c) in &self.children {
            // SAFETY: sending a signal to a child process id we own has no memory effects.
            unsafe { libc::kill(c.id() as libc::pid_t, libc::SIGTERM) };
        }
        let deadline = Instant::now() + Duration::from_secs(3);
        for (name, c) in &mut self.children {
            while Instant::now() < deadline {
                if let Ok(Some(_)) = c.try_wait() {
                    break;
                }
                std::thread::sleep(Duration::from_millis(10));
            }
            if let Ok(None) = c.try_wait() {
                tracing::warn!("photopose {name} did not stop; killing it");
                let _ = c.kill();
                let _ = c.wait();
            }
        }
        self.children.clear();
    }
}

impl Drop for Processes {
    fn drop(&mut self) {
        self.stop();
    }
}

/// A labelled line of a plot panel.
type Line = (String, Vec<(f64, f64)>);

/// What the demo saw of each object, in the estimator's order.
struct Run {
    tracks: Vec<(String, Record)>,
}

impl Run {
    fn new(names: &[String]) -> Self {
        Self {
            tracks: names.iter().map(|n| (n.clone(), Record::default())).collect(),
        }
    }

    /// Files each object's truth by name (a lone truth goes to a lone object).
    fn truth(&mut self, set: &PoseSet) {
        let lone = self.tracks.len() == 1 && set.count == 1;
        for (name, record) in &mut self.tracks {
            if let Some(t) = set.get(name).or(if lone { set.first() } else { None }) {
                record.truth.insert(t.frame_id, *t);
            }
        }
    }

    /// Files each object's pose, received at `now`.
    fn poses(&mut self, set: &PoseSet, now: u64) {
        for (name, record) in &mut self.tracks {
            if let Some(p) = set.get(name) {
                record.poses.push((*p, now));
            }
        }
    }

    /// The status line: the first object's figures, then the others' errors.
    fn status(&self, elapsed: f64) -> String {
        let mut line = self.tracks[0].1.status(elapsed);
        if self.tracks.len() > 1 {
            for (name, record) in &self.tracks {
                let errors = Samples::new(record.tracked().map(|(p, t, _)| position_error(p, t)));
                line += &format!(" | {name} {} p95 {:.1} mm", record.state(), errors.percentile(95.0));
            }
        }
        line
    }

    /// x, y, z against time: each object's truth and estimate, one panel per axis.
    fn plot(&self) -> Result<image::RgbImage, plot::PlotError> {
        let t0 = (self.tracks.iter())
            .filter_map(|(_, r)| r.truth.values().next().map(|t| t.capture_time_ns))
            .min()
            .unwrap_or(0);
        let time = |ns: u64| ns.saturating_sub(t0) as f64 * 1e-9;
        // Per axis, per object: (label, points) of the truth, then of the estimate.
        let one = self.tracks.len() == 1;
        let data: Vec<Vec<Line>> = (0..3)
            .map(|i| {
                let mut lines = Vec::new();
                for (name, r) in &self.tracks {
                    let label = |what: &str| {
                        if one {
                            what.to_string()
                        } else {
                            format!("{name} {what}")
                        }
                    };
                    let truth = r.truth.values().map(|t| (time(t.capture_time_ns), t.position_mm[i]));
                    let estimate = r.poses.iter().map(|(p, _)| (time(p.capture_time_ns), p.position_mm[i]));
                    lines.push((label("truth"), truth.collect()));
                    lines.push((label("estimate"), estimate.collect()));
                }
                lines
            })
            .collect();
        let titles = ["x (hand frame)", "y (hand frame)", "z (hand frame)"];
        let panels: Vec<Panel> = (data.iter().zip(titles))
            .map(|(lines, title)| Panel {
                title,
                x_label: "time [s]",
                y_label: "position [mm]",
                series: (lines.iter().enumerate())
                    .map(|(k, (label, points))| Series {
                        label,
                        points,
                        color: PALETTE[k % PALETTE.len()],
                    })
                    .collect(),
                ..Default::default()
            })
            .collect();
        plot::panels(&panels, 1200, 900)
    }

    /// The summary, one block per object.
    fn summary(&self) -> String {
        if self.tracks.len() == 1 {
            return self.tracks[0].1.summary();
        }
        let blocks: Vec<String> = self
            .tracks
            .iter()
            .map(|(name, record)| format!("{name}:\n{}", record.summary()))
            .collect();
        blocks.join("\n")
    }
}

/// What the demo saw of one object: the truth of every frame and every pose with the
/// time it arrived.
#[derive(Default)]
struct Record {
    truth: BTreeMap<u64, PoseMsg>,
    poses: Vec<(PoseMsg, u64)>,
}

/// Position error of a pose against the truth of its frame, mm.
fn position_error(p: &PoseMsg, t: &PoseMsg) -> f64 {
    (0..3)
        .map(|i| (p.position_mm[i] - t.position_mm[i]).powi(2))
        .sum::<f64>()
        .sqrt()
}

impl Record {
    /// The index of the first tracking pose: the end of the first acquisition.
    fn acquired(&self) -> usize {
        let tracking = |(p, _): &&(PoseMsg, u64)| p.status == Status::Tracking as u32;
        self.poses.iter().position(|p| tracking(&p)).unwrap_or(self.poses.len())
    }

    /// Tracking poses after the first (the acquisition), with their truth.
    fn tracked(&self) -> impl Iterator<Item = (&PoseMsg, &PoseMsg, u64)> {
        self.poses
            .iter()
            .skip(self.acquired() + 1)
            .filter(|(p, _)| p.status == Status::Tracking as u32)
            .filter_map(|(p, at)| Some((p, self.truth.get(&p.frame_id)?, *at)))
    }

    /// Frames the estimator skipped while tracking, and the frames from each tracking
    /// pose to the next. The frames after a search of the whole frame (an acquisition or
    /// the relocation after it: more generations than the median pose) are left out, as
    /// `photopose latency` does: it takes many frame periods.
    fn dropped(&self) -> (u64, u64) {
        let median = Samples::new(self.poses.iter().map(|(p, _)| p.generations as f64)).median();
        let (mut dropped, mut span) = (0, 0);
        for w in self.poses.windows(2) {
            let (a, b) = (&w[0].0, &w[1].0);
            if a.generations as f64 > median {
                continue;
            }
            let gap = b.frame_id.saturating_sub(a.frame_id + 1);
            dropped += gap;
            span += gap + 1;
        }
        (dropped, span)
    }

    /// Frames that went by during the acquisition.
    fn acquisition_frames(&self) -> u64 {
        match (self.truth.keys().next(), self.poses.get(self.acquired() + 1)) {
            (Some(&a), Some((b, _))) => b.frame_id.saturating_sub(a + 1),
            _ => 0,
        }
    }

    /// The camera's frame rate so far.
    fn fps(&self) -> f64 {
        match (self.truth.values().next(), self.truth.values().next_back()) {
            (Some(a), Some(b)) if b.capture_time_ns > a.capture_time_ns => {
                (self.truth.len() - 1) as f64 / ((b.capture_time_ns - a.capture_time_ns) as f64 * 1e-9)
            }
            _ => 0.0,
        }
    }

    /// One line of figures so far, `elapsed` seconds in.
    fn status(&self, elapsed: f64) -> String {
        let errors = Samples::new(self.tracked().map(|(p, t, _)| position_error(p, t)));
        let latency = Samples::new(
            self.poses
                .iter()
                .map(|(p, _)| (p.publish_time_ns.saturating_sub(p.capture_time_ns)) as f64 * 1e-6),
        );
        let state = self.state();
        format!(
            "{elapsed:5.1} s | frames {:5} ({:4.1} fps) | poses {:5} dropped {:3} | {state} | error {:5.1} mm (p95 {:5.1}) | capture→pose p50 {:5.1} ms p99 {:5.1} ms",
            self.truth.len(),
            self.fps(),
            self.poses.len(),
            self.dropped().0,
            errors.median(),
            errors.percentile(95.0),
            latency.median(),
            latency.percentile(99.0)
        )
    }

    /// The newest pose's status, or `acquiring`.
    fn state(&self) -> String {
        self.poses
            .last()
            .map(|(p, _)| crate::client::status_name(p.status))
            .unwrap_or_else(|| "acquiring".into())
    }

    /// The report printed at the end.
    fn summary(&self) -> String {
        let errors = Samples::new(self.tracked().map(|(p, t, _)| position_error(p, t)));
        let latency = Samples::new(
            self.poses
                .iter()
                .skip(1)
                .map(|(p, _)| p.publish_time_ns.saturating_sub(p.capture_time_ns) as f64 * 1e-6),
        );
        let end_to_end = Samples::new(
            self.poses
                .iter()
                .skip(1)
                .map(|(p, at)| at.saturating_sub(p.capture_time_ns) as f64 * 1e-6),
        );
        let tracking = self
            .poses
            .iter()
            .filter(|(p, _)| p.status == Status::Tracking as u32)
            .count();
        // From the first frame to the first tracking pose (an object acquired in the
        // background is published as `searching` meanwhile).
        let first_frame = self.truth.values().next().map(|t| t.capture_time_ns);
        let acquisition = match (first_frame, self.poses.get(self.acquired())) {
            (Some(t0), Some((p, _))) => p.publish_time_ns.saturating_sub(t0) as f64 * 1e-9,
            _ => f64::NAN,
        };
        let (dropped, span) = self.dropped();
        format!(
            "frames {}  poses {} ({tracking} tracking)  dropped while tracking {dropped} of {span} ({:.2} %)\n\
             acquisition {acquisition:.2} s (first frame → first tracking pose; {} frames went by)\n\
             position error (tracking): mean {:.1} mm  p95 {:.1} mm  max {:.1} mm\n\
             latency capture→pose published: p50 {:.1} ms  p99 {:.1} ms;  capture→pose received: p50 {:.1} ms  p99 {:.1} ms",
            self.truth.len(),
            self.poses.len(),
            100.0 * dropped as f64 / span.max(1) as f64,
            self.acquisition_frames(),
            errors.mean(),
            errors.percentile(95.0),
            errors.max(),
            latency.median(),
            latency.percentile(99.0),
            end_to_end.median(),
            end_to_end.percentile(99.0)
        )
    }
}
