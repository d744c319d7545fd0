//! `photopose capture`: publishes side-by-side frames on `photopose/stereo_frames`,
//! rendered in place into loaned shared memory, and each frame's ground truth on
//! `photopose/truth`.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{anyhow, Result};

use crate::capture::{pose_msg, Source, Trajectory};
use crate::config::Config;
use crate::ipc::{send_pose, Ipc};
use crate::messages::{monotonic_ns, pixel_format, FrameHeader, TRUTH_SERVICE};
use crate::render::{Renderer, SceneSpec};

/// Publish stereo frames.
#[derive(clap::Args, Debug)]
pub struct CaptureArgs {
    /// `synthetic[:SCENE.toml]`: the synthetic camera on a scene file (default
    /// `config/scenes/rocket.toml`), its card moving along a smooth loop.
    #[arg(long, default_value = "synthetic")]
    pub source: String,
    /// Frame rate, frames per second.
    #[arg(long, default_value_t = 60.0)]
    pub fps: f64,
    /// Peak speed of the synthetic card, mm/s.
    #[arg(long, default_value_t = 150.0)]
    pub speed: f64,
    /// Stop after this many seconds (0: run until interrupted).
    #[arg(long, default_value_t = 0.0)]
    pub seconds: f64,
    /// Configuration file; built-in defaults otherwise.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
}

pub fn run(args: &CaptureArgs) -> Result<()> {
    if !(args.fps.is_finite() && args.fps > 0.0) {
        return Err(anyhow!("--fps {} must be a positive number", args.fps));
    }
    let config = Config::load(args.config.as_deref())?;
    let Source::Synthetic(scene_path) = Source::parse(&args.source)?;
    let spec = SceneSpec::load(&scene_path)?;
    let rig = config.calibration.rig(spec.resolution.into())?;
    let mut scene = spec.build(&config.left_from_hand)?;
    let trajectory = Trajectory::with_peak_speed(scene.card.hand_from_model, args.speed);
    let (w, h) = (rig.width as usize, rig.height as usize);
    let renderer = Renderer::new(&rig, &config.left_from_hand, &scene);
    let bytes = renderer.frame_len();
    let ipc = Ipc::new("photopose-capture")?;
    let frames = ipc.frame_publisher(bytes)?;
    let truth = ipc.pose_publisher(TRUTH_SERVICE)?;
    tracing::info!(
        "capture: {} at {} fps, {w}x{h} per eye, card loop {:.1} s at up to {:.0} mm/s",
        scene_path.display(),
        args.fps,
        trajectory.period_s,
        args.speed
    );
    let start = Instant::now();
    let period = Duration::from_secs_f64(1.0 / args.fps);
    let mut report = Instant::now();
    let mut published_since = 0u32;
    for frame_id in 0u64.. {
        let elapsed = start.elapsed();
        if args.seconds > 0.0 && elapsed.as_secs_f64() >= args.seconds {
            break;
        }
        // Frame pacing: never faster than the camera; the card moves by frame time.
        let due = period * frame_id as u32;
        if !ipc.wait(due.saturating_sub(elapsed)) {
            break;
        }
        let pose = trajectory.pose_at(frame_id as f64 / args.fps);
        scene.card.hand_from_model = pose;
        let mut sample = frames
            .loan_slice(bytes)
            .map_err(|e| anyhow!("cannot loan a frame sample: {e:?}"))?;
        renderer.render_into(&scene, sample.payload_mut());
        let capture_time_ns = monotonic_ns();
        *sample.user_header_mut() = FrameHeader {
            frame_id,
            capture_time_ns,
            width: w as u32,
            height: h as u32,
            pixel_format: pixel_format::RGB8,
            row_stride: (2 * w * 3) as u32,
        };
        sample
            .send()
            .map_err(|e| anyhow!("cannot send frame {frame_id}: {e:?}"))?;
        send_pose(&truth, pose_msg(frame_id, capture_time_ns, &pose, scene.card.size_mm))?;
        published_since += 1;
        if report.elapsed() >= Duration::from_secs(2) {
            tracing::info!(
                "capture: frame {frame_id}, {:.1} fps",
                published_since as f64 / report.elapsed().as_secs_f64()
            );
            report = Instant::now();
            published_since = 0;
        }
    }
    Ok(())
}
