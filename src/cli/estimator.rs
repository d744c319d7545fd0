//! `photopose estimator`: tracks the model on the newest frame of
//! `photopose/stereo_frames` with a population that lives across frames, and
//! publishes one pose per processed frame on `photopose/poses`.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{anyhow, Result};

use crate::config::Config;
use crate::estimate::Prepared;
use crate::frame::StereoImages;
use crate::ipc::{send_pose, Ipc};
use crate::messages::{monotonic_ns, pixel_format, FrameHeader, PoseMsg, POSES_SERVICE};
use crate::model::PhotoModel;
use crate::tracking::Tracker;

/// Track the model in the frame stream.
#[derive(clap::Args, Debug)]
pub struct EstimatorArgs {
    /// Photo-model file (from `photopose model`).
    #[arg(long, value_name = "MODEL")]
    pub model: PathBuf,
    /// Configuration file; built-in defaults otherwise.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Stop after this many seconds (0: run until interrupted).
    #[arg(long, default_value_t = 0.0)]
    pub seconds: f64,
}

pub fn run(args: &EstimatorArgs) -> Result<()> {
    let config = Config::load(args.config.as_deref())?;
    let model = PhotoModel::load(&args.model)?;
    let ipc = Ipc::new("photopose-estimator")?;
    let frames = ipc.frame_subscriber()?;
    let poses = ipc.pose_publisher(POSES_SERVICE)?;
    let mut tracker = Tracker::new(&config, config.ga.seed);
    let start = Instant::now();
    let mut last_id: Option<u64> = None;
    let (mut processed, mut dropped) = (0u64, 0u64);
    let mut report = Instant::now();
    while ipc.wait(Duration::from_millis(1)) {
        if args.seconds > 0.0 && start.elapsed().as_secs_f64() >= args.seconds {
            break;
        }
        // Always the newest frame: older ones still queued are dropped.
        let mut newest = None;
        while let Some(sample) = frames.receive().map_err(|e| anyhow!("cannot receive a frame: {e:?}"))? {
            newest = Some(sample);
        }
        let Some(sample) = newest else { continue };
        let header: FrameHeader = *sample.user_header();
        if let Some(last) = last_id {
            if header.frame_id <= last {
                // A restarted capture counts from 0 again.
                tracing::info!("estimator: frame ids restarted at {}", header.frame_id);
            } else {
                dropped += header.frame_id - last - 1;
            }
        }
        last_id = Some(header.frame_id);
        if header.pixel_format != pixel_format::RGB8 {
            tracing::warn!(
                "estimator: frame {} has pixel format {}, expected RGB8; skipped",
                header.frame_id,
                header.pixel_format
            );
            continue;
        }
        let Some(images) = StereoImages::from_rgb8_sbs(
            header.width as usize,
            header.height as usize,
            header.row_stride as usize,
            sample.payload(),
        ) else {
            tracing::warn!(
                "estimator: frame {} is smaller than its header says; skipped",
                header.frame_id
            );
            continue;
        };
        drop(sample);
        let prepared = match Prepared::new(&model, &images, &config) {
            Ok(p) => p,
            Err(e) => {
                tracing::warn!("estimator: frame {}: {e}", header.frame_id);
                continue;
            }
        };
        let problem = prepared.problem(&model, &config);
        let est = tracker.step(&problem);
        let b = &est.best;
        let pose = PoseMsg {
            frame_id: header.frame_id,
            capture_time_ns: header.capture_time_ns,
            publish_time_ns: monotonic_ns(),
            position_mm: b.position.into(),
            orientation_wxyz: b.orientation_wxyz(),
            size_mm: b.size_mm(model.l_p, model.b_p),
            fitness: est.fitness.f,
            generations: est.generations,
            status: est.status,
        };
        send_pose(&poses, pose)?;
        processed += 1;
        if report.elapsed() >= Duration::from_secs(2) {
            tracing::info!(
                "estimator: frame {}, {processed} processed, {dropped} dropped, F {:.3}, status {}",
                header.frame_id,
                est.fitness.f,
                est.status
            );
            report = Instant::now();
        }
    }
    tracing::info!("estimator: {processed} frames processed, {dropped} dropped");
    Ok(())
}
