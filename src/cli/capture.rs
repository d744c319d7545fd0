//! `photopose capture`: publishes side-by-side frames on `photopose/stereo_frames`,
//! written by the source straight into loaned shared memory (not zeroed first: an HD
//! frame is megabytes the source overwrites anyway), and each frame's ground truth
//! (when known) on `photopose/truth`; optionally records them. Every 2 s it logs the
//! frame rate and how long a frame takes from loan to send.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Result};

use crate::capture::frame_buf::write_uninit;
use crate::capture::record::Recorder;
use crate::capture::replay::ReplaySource;
use crate::capture::synthetic::SyntheticSource;
use crate::capture::{FrameSource, Geometry, Source};
use crate::config::Config;
use crate::transport::ipc::{send_poses, wake_up, FramePublisher, Ipc, PosePublisher, Waker};
use crate::transport::messages::{monotonic_ns, FrameHeader, ObjectName, FRAMES_SERVICE, TRUTH_SERVICE};

/// Publish stereo frames.
#[derive(clap::Args, Debug)]
pub struct CaptureArgs {
    /// `synthetic[:SCENE.toml]` (the synthetic camera on a scene file, default
    /// `config/scenes/rocket.toml`, its card moving along a smooth loop), `replay:DIR`
    /// (a recorded sequence) or `zed` (a ZED 2i over V4L2; build with `--features zed`).
    #[arg(long, default_value = "synthetic")]
    pub source: String,
    /// Frame rate, frames per second (synthetic default 60; replay default: as recorded;
    /// zed: one of the resolution's rates, default the fastest).
    #[arg(long)]
    pub fps: Option<f64>,
    /// Zed: the camera's resolution per eye, 2K, FHD, HD (default) or VGA.
    #[arg(long, value_name = "NAME")]
    pub resolution: Option<String>,
    /// Zed: the video device (default: the first ZED found in sysfs).
    #[arg(long, value_name = "/dev/videoN")]
    pub device: Option<PathBuf>,
    /// Peak speed of the synthetic card, mm/s.
    #[arg(long, default_value_t = 150.0)]
    pub speed: f64,
    /// Synthetic: also show the card of this scene file (its photo, box, pose and size),
    /// on a loop of its own; repeatable. Cards must not overlap in the images.
    #[arg(long = "card", value_name = "SCENE.toml")]
    pub cards: Vec<PathBuf>,
    /// Replay: start again after the last frame.
    #[arg(long = "loop")]
    pub looping: bool,
    /// Also record the frames (and their truth) into this directory, in the replay format.
    #[arg(long, value_name = "DIR")]
    pub record: Option<PathBuf>,
    /// Stop after this many seconds (0: run until interrupted or the replay ends).
    #[arg(long, default_value_t = 0.0)]
    pub seconds: f64,
    /// Configuration file; built-in defaults otherwise.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
}

/// Default synthetic frame rate: the ZED 2i's HD rate.
const DEFAULT_FPS: f64 = 60.0;

/// How often the frame rate and the cost of publishing a frame are logged.
const REPORT_EVERY: Duration = Duration::from_secs(2);

/// Opens the source, publishes its frames until it ends, `--seconds` pass or a stop
/// is requested, and finishes the recording.
pub fn run(args: &CaptureArgs) -> Result<()> {
    check_args(args)?;
    let config = Config::load(args.config.as_deref())?;
    let (mut source, calibration) = open_source(args, &config)?;
    let geometry = source.geometry();
    let mut recorder = match &args.record {
        Some(dir) => Some(start_recording(dir, args, geometry, calibration.as_deref())?),
        None => None,
    };
    let ipc = Ipc::new("photopose-capture")?;
    let mut out = Outlets {
        frames: ipc.frame_publisher(geometry.frame_len())?,
        waker: ipc.waker(FRAMES_SERVICE)?,
        truth: ipc.pose_publisher(TRUTH_SERVICE)?,
        objects: source.objects(),
        recorder: recorder.as_mut(),
    };
    tracing::info!("capture: {}", source.describe());
    let published = publish_all(args, &ipc, source.as_mut(), &mut out)?;
    tracing::info!("capture: {published} frames published");
    if let Some(summary) = source.summary() {
        tracing::info!("capture: {summary}");
    }
    if let (Some(rec), Some(dir)) = (recorder, &args.record) {
        let skipped = rec.skipped;
        let written = rec.finish()?;
        let dir = dir.display();
        tracing::info!("capture: recorded {written} frames into {dir} ({skipped} left out: the disk was behind)");
    }
    Ok(())
}

/// Rejects option values and combinations that cannot work.
fn check_args(args: &CaptureArgs) -> Result<()> {
    if let Some(fps) = args.fps.filter(|f| !(f.is_finite() && *f > 0.0)) {
        bail!("--fps {fps} must be a positive number");
    }
    if !(args.speed.is_finite() && args.speed >= 0.0) {
        bail!("--speed {} must be a number ≥ 0", args.speed);
    }
    let zed = Source::parse(&args.source)? == Source::Zed;
    if !zed && (args.resolution.is_some() || args.device.is_some()) {
        bail!("--resolution and --device apply to --source zed only");
    }
    if !args.cards.is_empty() && !matches!(Source::parse(&args.source)?, Source::Synthetic(_)) {
        bail!("--card applies to the synthetic camera only");
    }
    Ok(())
}

/// The frame source of `--source`, and the calibration file its frames need (zed).
fn open_source(args: &CaptureArgs, config: &Config) -> Result<(Box<dyn FrameSource>, Option<PathBuf>)> {
    Ok(match Source::parse(&args.source)? {
        Source::Synthetic(scene) => {
            let fps = args.fps.unwrap_or(DEFAULT_FPS);
            let source = SyntheticSource::with_cards(&scene, &args.cards, config, fps, args.speed)?;
            (Box::new(source), None)
        }
        Source::Replay(dir) => (Box::new(ReplaySource::open(&dir, args.fps, args.looping)?), None),
        Source::Zed => {
            let (zed, file) = zed::open(args, config)?;
            (zed, Some(file))
        }
    })
}

/// Starts recording into `dir`, with a copy of the calibration file the frames need.
fn start_recording(dir: &Path, args: &CaptureArgs, geometry: Geometry, calibration: Option<&Path>) -> Result<Recorder> {
    let recorder = Recorder::create(dir, geometry, &args.source)?;
    if let Some(file) = calibration {
        if let Some(name) = file.file_name() {
            std::fs::copy(file, dir.join(name))
                .map_err(|e| anyhow!("cannot copy {} into {}: {e}", file.display(), dir.display()))?;
        }
    }
    Ok(recorder)
}

/// Where each frame goes: the frame service (and its wake-up event), the truth
/// service, the recording.
struct Outlets<'r> {
    frames: FramePublisher,
    waker: Waker,
    truth: PosePublisher,
    /// The names of the source's objects, for their truth.
    objects: Vec<ObjectName>,
    recorder: Option<&'r mut Recorder>,
}

/// Publishes frames as they fall due; the number published.
fn publish_all(args: &CaptureArgs, ipc: &Ipc, source: &mut dyn FrameSource, out: &mut Outlets) -> Result<u64> {
    let start = Instant::now();
    let mut published = 0u64;
    let mut window = Window::default();
    while let Some(due) = source.next_due() {
        if args.seconds > 0.0 && start.elapsed().as_secs_f64() >= args.seconds {
            break;
        }
        if !ipc.wait(due.saturating_duration_since(Instant::now())) {
            break;
        }
        let loaned = Instant::now();
        if !publish_one(source, out, published)? {
            continue;
        }
        window.add(loaned.elapsed());
        published += 1;
        if window.started.elapsed() >= REPORT_EVERY {
            tracing::info!("capture: frame {}, {}", published - 1, window.line());
            window = Window::default();
        }
    }
    Ok(published)
}

/// Loans a sample, has the source write the frame straight into it (the sample is not
/// zeroed first), records it, and sends it and its truth as frame `count` (or the
/// number the source gave it: a replay's recorded one). False when the source had no
/// frame this time.
fn publish_one(source: &mut dyn FrameSource, out: &mut Outlets, count: u64) -> Result<bool> {
    let geometry = source.geometry();
    let mut sample = out
        .frames
        .loan_slice_uninit(geometry.frame_len())
        .map_err(|e| anyhow!("cannot loan a frame sample: {e:?}"))?;
    let Some(info) = write_uninit(source, sample.payload_mut())? else {
        return Ok(false);
    };
    // SAFETY: `write_uninit` returns a frame only when every byte of the payload it was
    // given, the whole sample, has been written.
    let mut sample = unsafe { sample.assume_init() };
    let frame_id = info.frame_id.unwrap_or(count);
    *sample.user_header_mut() = FrameHeader {
        frame_id,
        capture_time_ns: info.capture_time_ns,
        width: geometry.width,
        height: geometry.height,
        pixel_format: geometry.format.code(),
        row_stride: geometry.row_stride() as u32,
        publish_time_ns: 0,
    };
    if let Some(rec) = out.recorder.as_mut() {
        rec.record(frame_id, &info, sample.payload())?;
    }
    sample.user_header_mut().publish_time_ns = monotonic_ns();
    sample
        .send()
        .map_err(|e| anyhow!("cannot send frame {frame_id}: {e:?}"))?;
    wake_up(&out.waker);
    let truth = info.truth_set(&out.objects, frame_id);
    if truth.count > 0 {
        send_poses(&out.truth, &truth)?;
    }
    Ok(true)
}

/// Frames published since the last report and the time each took from loan to send
/// (the source writing it, recording, sending).
struct Window {
    started: Instant,
    frames: u32,
    total: Duration,
    max: Duration,
}

impl Default for Window {
    fn default() -> Self {
        Self {
            started: Instant::now(),
            frames: 0,
            total: Duration::ZERO,
            max: Duration::ZERO,
        }
    }
}

impl Window {
    fn add(&mut self, took: Duration) {
        self.frames += 1;
        self.total += took;
        self.max = self.max.max(took);
    }

    /// `"59.9 fps, loan → send mean 812 µs, max 1201 µs"`.
    fn line(&self) -> String {
        let fps = f64::from(self.frames) / self.started.elapsed().as_secs_f64();
        let mean = self.total.as_secs_f64() * 1e6 / f64::from(self.frames.max(1));
        format!(
            "{fps:.1} fps, loan → send mean {mean:.0} µs, max {:.0} µs",
            self.max.as_secs_f64() * 1e6
        )
    }
}

/// `--source zed`: the camera in the mode of `--resolution` and `--fps`, and its
/// calibration file.
#[cfg(feature = "zed")]
mod zed {
    use std::path::PathBuf;

    use anyhow::Result;

    use super::CaptureArgs;
    use crate::camera::calibration::Calibration;
    use crate::capture::zed::discovery::{calibration_dirs, find_calibration, Sysfs};
    use crate::capture::zed::stream::{Backoff, ZedSource};
    use crate::capture::zed::v4l2::V4l2Opener;
    use crate::capture::zed::Mode;
    use crate::capture::FrameSource;
    use crate::config::Config;

    /// The camera in the requested mode, and the calibration file found for it.
    pub fn open(args: &CaptureArgs, config: &Config) -> Result<(Box<dyn FrameSource>, PathBuf)> {
        let mode = Mode::select(args.resolution.as_deref(), args.fps)?;
        let opener = V4l2Opener {
            device: args.device.clone(),
            sysfs: Sysfs::default(),
        };
        let source = ZedSource::open(opener, mode, Backoff::default())?;
        let home = std::env::var_os("HOME").map(PathBuf::from);
        let dirs = calibration_dirs(home.as_deref());
        let file = find_calibration(
            config.calibration_file.as_deref(),
            source.info().serial.as_deref(),
            &dirs,
        )?;
        Calibration::load(&file)?.rig(mode.resolution)?;
        tracing::info!(
            "capture: calibration {} (the estimator needs the same file in [camera] calibration)",
            file.display()
        );
        Ok((Box::new(source), file))
    }
}

/// `--source zed` in a build without the camera.
#[cfg(not(feature = "zed"))]
mod zed {
    use std::path::PathBuf;

    use anyhow::{bail, Result};

    use super::CaptureArgs;
    use crate::capture::FrameSource;
    use crate::config::Config;

    /// Always an error saying how to build with the camera.
    pub fn open(_: &CaptureArgs, _: &Config) -> Result<(Box<dyn FrameSource>, PathBuf)> {
        bail!("--source zed needs the ZED camera support: rebuild with `cargo build --release --features zed`")
    }
}
