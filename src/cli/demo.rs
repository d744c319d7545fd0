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
use crate::transport::ipc::{Ipc, PoseSubscriber};
use crate::transport::messages::{monotonic_ns, PoseMsg, Status, POSES_SERVICE, TRUTH_SERVICE};

/// Run capture, estimator and controller together on the synthetic camera.
#[derive(clap::Args, Debug)]
pub struct DemoArgs {
    /// How long to run, seconds.
    #[arg(long, default_value_t = 20.0)]
    pub seconds: f64,
    /// Scene of the synthetic camera (its photo becomes the photo-model).
    #[arg(long, value_name = "SCENE.toml", default_value = DEFAULT_SCENE)]
    pub scene: PathBuf,
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
}

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
    let spec = SceneSpec::load(&args.scene)?;
    let model_path = std::env::temp_dir().join(format!("photopose-demo-{}.model", std::process::id()));
    super::scene_model(&spec, &config)?.save(&model_path)?;
    let ipc = Ipc::new("photopose-demo")?;
    let poses = ipc.pose_subscriber(POSES_SERVICE)?;
    let truths = ipc.pose_subscriber(TRUTH_SERVICE)?;
    let (mut procs, controller) = start_processes(args, &model_path)?;
    println!(
        "photopose demo: {} at up to {} mm/s, {} fps, for {} s (Ctrl-C stops early)",
        args.scene.display(),
        args.speed,
        args.fps,
        args.seconds
    );
    let watched = watch(args.seconds, &ipc, [&poses, &truths], &mut procs, controller.as_deref());
    procs.stop();
    drop((poses, truths));
    let _ = std::fs::remove_file(&model_path);
    let run = watched?;
    println!("{}", run.summary());
    plot::save(&run.plot()?, &args.plot)?;
    println!("trajectory plot: {}", args.plot.display());
    Ok(())
}

/// Starts `estimator` (on the model at `model_path`), `capture` (the synthetic camera)
/// and `controller`, each stopping by itself 10 s after the demo should have; returns
/// them and the slot holding the controller's last line.
fn start_processes(args: &DemoArgs, model_path: &Path) -> Result<(Processes, Option<Arc<Mutex<String>>>)> {
    let exe = std::env::current_exe().context("cannot find the photopose executable")?;
    // The children also stop by themselves, should the demo be killed.
    let limit = format!("{}", args.seconds + 10.0);
    let mut common: Vec<String> = Vec::new();
    if let Some(c) = &args.config {
        common.extend(["--config".into(), c.display().to_string()]);
    }
    let mut procs = Processes::default();
    let model = model_path.display().to_string();
    let estimator: &[&str] = &["--model", &model, "--seconds", &limit];
    procs.spawn(&exe, "estimator", &[estimator], &common, false)?;
    if let Some(rrd) = &args.rerun {
        let rrd = rrd.display().to_string();
        let viewer: &[&str] = &["--save", &rrd, "--model", &model, "--seconds", &limit];
        procs.spawn(&exe, "viewer", &[viewer], &common, false)?;
    }
    let scene = format!("synthetic:{}", args.scene.display());
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
    procs.spawn(&exe, "capture", &[capture], &common, false)?;
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
) -> Result<Record> {
    let mut run = Record::default();
    let start = Instant::now();
    let bar = status_bar();
    let every = Duration::from_millis(if bar.is_hidden() { 2000 } else { 250 });
    let mut shown = Instant::now();
    while ipc.wait(Duration::from_millis(1)) && start.elapsed().as_secs_f64() < seconds {
        let now = monotonic_ns();
        while let Some(s) = truths.receive().map_err(|e| anyhow!("cannot receive truth: {e:?}"))? {
            run.truth.insert(s.payload().frame_id, *s.payload());
        }
        while let Some(s) = poses.receive().map_err(|e| anyhow!("cannot receive a pose: {e:?}"))? {
            run.poses.push((*s.payload(), now));
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

/// What the demo saw: the truth of every frame and every pose with the time it arrived.
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
    /// Tracking poses after the first (the acquisition), with their truth.
    fn tracked(&self) -> impl Iterator<Item = (&PoseMsg, &PoseMsg, u64)> {
        self.poses
            .iter()
            .skip(1)
            .filter(|(p, _)| p.status == Status::Tracking as u32)
            .filter_map(|(p, at)| Some((p, self.truth.get(&p.frame_id)?, *at)))
    }

    /// Frames the estimator skipped while tracking: between its second and last pose
    /// (the first, the acquisition, takes many frame periods), and the frames it tracked.
    fn dropped(&self) -> (u64, u64) {
        match (self.poses.get(1), self.poses.last()) {
            (Some((a, _)), Some((b, _))) => {
                let span = b.frame_id.saturating_sub(a.frame_id) + 1;
                let posed = self.poses.len() as u64 - 1;
                (span.saturating_sub(posed), span)
            }
            _ => (0, 0),
        }
    }

    /// Frames that went by during the acquisition.
    fn acquisition_frames(&self) -> u64 {
        match (self.poses.first(), self.poses.get(1)) {
            (Some((a, _)), Some((b, _))) => b.frame_id.saturating_sub(a.frame_id + 1),
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
        let state = self
            .poses
            .last()
            .map(|(p, _)| crate::client::status_name(p.status))
            .unwrap_or_else(|| "acquiring".into());
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
        let acquisition = self
            .poses
            .first()
            .map(|(p, _)| p.publish_time_ns.saturating_sub(p.capture_time_ns) as f64 * 1e-9)
            .unwrap_or(f64::NAN);
        let (dropped, span) = self.dropped();
        format!(
            "frames {}  poses {} ({tracking} tracking)  dropped while tracking {dropped} of {span} ({:.2} %)\n\
             acquisition {acquisition:.2} s (first frame → first pose; {} frames went by)\n\
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

    /// x, y, z against time: truth and estimate, one panel each.
    fn plot(&self) -> Result<image::RgbImage, plot::PlotError> {
        let t0 = self.truth.values().next().map(|t| t.capture_time_ns).unwrap_or(0);
        let time = |ns: u64| ns.saturating_sub(t0) as f64 * 1e-9;
        let axis = |i: usize| {
            let truth: Vec<(f64, f64)> = self
                .truth
                .values()
                .map(|t| (time(t.capture_time_ns), t.position_mm[i]))
                .collect();
            let estimate: Vec<(f64, f64)> = self
                .poses
                .iter()
                .map(|(p, _)| (time(p.capture_time_ns), p.position_mm[i]))
                .collect();
            (truth, estimate)
        };
        let data: Vec<_> = (0..3).map(axis).collect();
        let titles = ["x (hand frame)", "y (hand frame)", "z (hand frame)"];
        let panels: Vec<Panel> = data
            .iter()
            .zip(titles)
            .map(|((truth, estimate), title)| Panel {
                title,
                x_label: "time [s]",
                y_label: "position [mm]",
                series: vec![
                    Series {
                        label: "truth",
                        points: truth,
                        color: PALETTE[0],
                    },
                    Series {
                        label: "estimate",
                        points: estimate,
                        color: PALETTE[1],
                    },
                ],
                ..Default::default()
            })
            .collect();
        plot::panels(&panels, 1200, 900)
    }
}
