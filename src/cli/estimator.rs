//! `photopose estimator`: tracks the model on the newest frame of
//! `photopose/stereo_frames` with a population that lives across frames, and
//! publishes one pose per processed frame on `photopose/poses`.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{anyhow, Result};

use crate::camera::StereoRig;
use crate::config::{Config, Mode};
use crate::estimate::{scorer_for, Prepared};
use crate::fitness::PointSet;
use crate::frame::StereoImages;
use crate::ga::{Bounds, Problem};
use crate::ipc::{send_pose, Ipc};
use crate::lookup::{LevelLookup, LookupImage, SbsBytes};
use crate::messages::{monotonic_ns, pixel_format, FrameHeader, PoseMsg, POSES_SERVICE};
use crate::model::PhotoModel;
use crate::tracking::{search_windows, Tracker};

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
    // What tracking frames reuse: scorer, search space, full-resolution points, and the
    // lookup images refilled in place around the predicted pose.
    let scorer = scorer_for(&model, &config);
    let classes = config.fitness.classes();
    let bounds = Bounds::new(&config.search, &model, config.ga.mode == Mode::Robust);
    let points = [PointSet::from_model(&model, &scorer.params, 1)];
    let mut level: Option<LevelLookup> = None;
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
        };
        if header.pixel_format != pixel_format::RGB8 || !frame.is_complete() {
            tracing::warn!(
                "estimator: frame {} skipped: pixel format {} (expected RGB8) or payload smaller than its header says",
                header.frame_id,
                header.pixel_format
            );
            continue;
        }
        let rig = match config.calibration.rig_for_image(header.width, header.height) {
            Ok(rig) => rig,
            Err(e) => {
                tracing::warn!("estimator: frame {}: {e}", header.frame_id);
                continue;
            }
        };
        let est = match tracker.prediction().filter(|_| config.tracking.level == 0) {
            Some(genes) => {
                let lv = level.get_or_insert_with(|| outside_lookup(&rig));
                if lv.rig != rig {
                    *lv = outside_lookup(&rig);
                }
                let pose = bounds.decode(&genes);
                let rois = search_windows(
                    &rig,
                    &config.left_from_hand,
                    &pose,
                    scorer.box_px,
                    WINDOW_GROW,
                    WINDOW_MIN_PX,
                );
                scorer.refill(lv, &frame, &rois, &classes);
                drop(sample);
                let problem = Problem::new(&scorer, std::slice::from_ref(lv), &points, bounds, config.ga.threads);
                tracker.step(&problem)
            }
            None => {
                let images = StereoImages::from_rgb8_sbs(frame.width, frame.height, frame.row_stride, frame.bytes);
                drop(sample);
                let Some(images) = images else { continue };
                let prepared = Prepared::new(&model, &images, &config)?;
                tracker.step(&prepared.problem(&config))
            }
        };
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

/// Growth of the prepared window around the predicted model, as a share of its size,
/// and its least margin in pixels.
const WINDOW_GROW: f64 = 0.5;
const WINDOW_MIN_PX: f64 = 40.0;

/// Full-resolution lookup images of outside texels for `rig`'s image size.
fn outside_lookup(rig: &StereoRig) -> LevelLookup {
    let (w, h) = (rig.width as usize, rig.height as usize);
    LevelLookup {
        scale: 1.0,
        rig: rig.clone(),
        left: LookupImage::outside(w, h),
        right: LookupImage::outside(w, h),
    }
}
