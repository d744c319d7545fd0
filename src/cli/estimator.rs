//! `photopose estimator`: tracks the model on the newest frame of
//! `photopose/stereo_frames` with a population that lives across frames, and
//! publishes one pose per processed frame on `photopose/poses`.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{anyhow, Result};

use crate::config::Config;
use crate::estimator::model::PhotoModel;
use crate::estimator::realtime::{self, RealtimeSettings};
use crate::estimator::tracking::{Estimate, StreamTracker, TrackState};
use crate::transport::ipc::{send_pose, wake_up, Ipc};
use crate::transport::messages::{
    monotonic_ns, validate_frame, FrameHeader, PoseMsg, Status, FRAMES_SERVICE, POSES_SERVICE,
};
use crate::vision::lookup::SbsBytes;

use super::skips::FrameSkips;

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

/// Tracks until `--seconds` pass or a stop is requested, one pose per processed frame.
pub fn run(args: &EstimatorArgs) -> Result<()> {
    let config = Config::load(args.config.as_deref())?;
    let model = PhotoModel::load(&args.model)?;
    apply_realtime(&config.realtime);
    let ipc = Ipc::new("photopose-estimator")?;
    let frames = ipc.frame_subscriber()?;
    let poses = ipc.pose_publisher(POSES_SERVICE)?;
    let (wake, waker) = (ipc.wake(FRAMES_SERVICE)?, ipc.waker(POSES_SERVICE)?);
    let mut tracker = StreamTracker::new(model, config);
    let start = Instant::now();
    let mut last_id: Option<u64> = None;
    let (mut processed, mut dropped) = (0u64, 0u64);
    let mut skipped = FrameSkips::default();
    let mut report = Instant::now();
    // Woken by the camera; the timeout only bounds how late a stop request is noticed.
    while ipc.wait_for(&wake, Duration::from_millis(50)) {
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
        // A header that disagrees with its payload must not steer reads of it.
        let format = match validate_frame(&header, sample.payload().len()) {
            Ok(format) => format,
            Err(fault) => {
                skipped.fault(header.frame_id, &fault);
                continue;
            }
        };
        match last_id {
            Some(last) if header.frame_id > last => dropped += header.frame_id - last - 1,
            Some(_) => tracing::info!("estimator: frame ids restarted at {}", header.frame_id),
            None => {}
        }
        last_id = Some(header.frame_id);
        let frame = SbsBytes {
            bytes: sample.payload(),
            width: header.width as usize,
            height: header.height as usize,
            row_stride: header.row_stride as usize,
            format,
        };
        if let Err(e) = tracker.prepare(&frame) {
            skipped.unusable(header.frame_id, &e);
            continue;
        }
        drop(sample);
        let Some(est) = tracker.step() else { continue };
        let mut pose = pose_msg(tracker.model(), &est, header.frame_id, header.capture_time_ns);
        pose.publish_time_ns = monotonic_ns();
        send_pose(&poses, pose)?;
        wake_up(&waker);
        processed += 1;
        if report.elapsed() >= Duration::from_secs(2) {
            tracing::info!(
                "estimator: frame {}, {processed} processed, {dropped} dropped, F {:.3}, status {}",
                header.frame_id,
                est.fitness.f,
                wire_status(est.state).name()
            );
            report = Instant::now();
        }
    }
    tracing::info!(
        "estimator: {processed} frames processed, {dropped} dropped, skipped: {}",
        skipped.summary()
    );
    Ok(())
}

/// Applies the `[realtime]` settings (when not the defaults) to this process and logs
/// what took effect.
fn apply_realtime(settings: &RealtimeSettings) {
    if *settings == RealtimeSettings::default() {
        return;
    }
    let (thread, locked) = realtime::apply_to_process(settings);
    tracing::info!(
        "estimator: realtime: main thread on CPU {}, SCHED_FIFO priority {}, memory {}",
        thread.pinned.map_or("any".into(), |c| c.to_string()),
        thread.fifo_priority.map_or("none".into(), |p| p.to_string()),
        if locked { "locked" } else { "pageable" }
    );
}

/// The wire status of a tracking state.
pub fn wire_status(state: TrackState) -> Status {
    match state {
        TrackState::Tracking => Status::Tracking,
        TrackState::Searching => Status::Searching,
        TrackState::Lost => Status::Lost,
    }
}

/// The pose message of an estimate of `model` for frame `frame_id` (publish time not
/// set), [sanitized](PoseMsg::sanitize): finite, unit quaternion, `lost` when it cannot be.
pub fn pose_msg(model: &PhotoModel, est: &Estimate, frame_id: u64, capture_time_ns: u64) -> PoseMsg {
    let b = &est.best;
    let mut pose = PoseMsg {
        frame_id,
        capture_time_ns,
        publish_time_ns: 0,
        position_mm: b.position.into(),
        orientation_wxyz: b.orientation_wxyz(),
        size_mm: b.size_mm(model.l_p, model.b_p),
        fitness: est.fitness.f,
        generations: est.generations,
        status: wire_status(est.state).into(),
    };
    pose.sanitize();
    pose
}
