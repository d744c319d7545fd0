//! `photopose capture`: publishes side-by-side frames on `photopose/stereo_frames`,
//! written by the source straight into loaned shared memory, and each frame's ground
//! truth (when known) on `photopose/truth`; optionally records them.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Result};

use crate::capture::record::Recorder;
use crate::capture::replay::ReplaySource;
use crate::capture::synthetic::SyntheticSource;
use crate::capture::{FrameSource, Source};
use crate::config::Config;
use crate::transport::ipc::{send_pose, wake_up, Ipc};
use crate::transport::messages::{monotonic_ns, FrameHeader, FRAMES_SERVICE, TRUTH_SERVICE};

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

pub fn run(args: &CaptureArgs) -> Result<()> {
    if let Some(fps) = args.fps.filter(|f| !(f.is_finite() && *f > 0.0)) {
        bail!("--fps {fps} must be a positive number");
    }
    if !(args.speed.is_finite() && args.speed >= 0.0) {
        bail!("--speed {} must be a number ≥ 0", args.speed);
    }
    let source = Source::parse(&args.source)?;
    if source != Source::Zed && (args.resolution.is_some() || args.device.is_some()) {
        bail!("--resolution and --device apply to --source zed only");
    }
    let config = Config::load(args.config.as_deref())?;
    let mut calibration = None;
    let mut source: Box<dyn FrameSource> = match source {
        Source::Synthetic(scene) => Box::new(SyntheticSource::open(
            &scene,
            &config,
            args.fps.unwrap_or(DEFAULT_FPS),
            args.speed,
        )?),
        Source::Replay(dir) => Box::new(ReplaySource::open(&dir, args.fps, args.looping)?),
        Source::Zed => {
            let (zed, file) = zed::open(args, &config)?;
            calibration = Some(file);
            zed
        }
    };
    let geometry = source.geometry();
    let mut recorder = match &args.record {
        Some(dir) => Some(Recorder::create(dir, geometry, &args.source)?),
        None => None,
    };
    if let (Some(dir), Some(file)) = (&args.record, &calibration) {
        // The recording keeps the calibration its frames need.
        if let Some(name) = file.file_name() {
            std::fs::copy(file, dir.join(name))
                .map_err(|e| anyhow!("cannot copy {} into {}: {e}", file.display(), dir.display()))?;
        }
    }
    let ipc = Ipc::new("photopose-capture")?;
    let frames = ipc.frame_publisher(geometry.frame_len())?;
    let waker = ipc.waker(FRAMES_SERVICE)?;
    let truth = ipc.pose_publisher(TRUTH_SERVICE)?;
    tracing::info!("capture: {}", source.describe());

    let start = Instant::now();
    let mut report = Instant::now();
    let (mut published, mut since_report) = (0u64, 0u32);
    while let Some(due) = source.next_due() {
        if args.seconds > 0.0 && start.elapsed().as_secs_f64() >= args.seconds {
            break;
        }
        if !ipc.wait(due.saturating_duration_since(Instant::now())) {
            break;
        }
        let mut sample = frames
            .loan_slice(geometry.frame_len())
            .map_err(|e| anyhow!("cannot loan a frame sample: {e:?}"))?;
        let Some(info) = source.fill(sample.payload_mut())? else {
            continue;
        };
        let frame_id = published;
        *sample.user_header_mut() = FrameHeader {
            frame_id,
            capture_time_ns: info.capture_time_ns,
            width: geometry.width,
            height: geometry.height,
            pixel_format: geometry.format.code(),
            row_stride: geometry.row_stride() as u32,
            publish_time_ns: 0,
        };
        if let Some(rec) = recorder.as_mut() {
            rec.record(frame_id, &info, sample.payload())?;
        }
        sample.user_header_mut().publish_time_ns = monotonic_ns();
        sample
            .send()
            .map_err(|e| anyhow!("cannot send frame {frame_id}: {e:?}"))?;
        wake_up(&waker);
        if let Some(t) = &info.truth {
            send_pose(&truth, t.pose_msg(frame_id, info.capture_time_ns))?;
        }
        published += 1;
        since_report += 1;
        if report.elapsed() >= Duration::from_secs(2) {
            tracing::info!(
                "capture: frame {frame_id}, {:.1} fps",
                since_report as f64 / report.elapsed().as_secs_f64()
            );
            report = Instant::now();
            since_report = 0;
        }
    }
    tracing::info!("capture: {published} frames published");
    if let Some(summary) = source.summary() {
        tracing::info!("capture: {summary}");
    }
    if let Some(rec) = recorder {
        let skipped = rec.skipped;
        let written = rec.finish()?;
        let dir = args.record.as_deref().unwrap_or(std::path::Path::new("")).display();
        tracing::info!("capture: recorded {written} frames into {dir} ({skipped} left out: the disk was behind)");
    }
    Ok(())
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

    pub fn open(_: &CaptureArgs, _: &Config) -> Result<(Box<dyn FrameSource>, PathBuf)> {
        bail!("--source zed needs the ZED camera support: rebuild with `cargo build --release --features zed`")
    }
}
