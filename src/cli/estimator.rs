//! `photopose estimator`: tracks each model on the newest frame of
//! `photopose/stereo_frames`, each with a population of its own that lives across
//! frames, and publishes one pose set per processed frame on `photopose/poses`.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Result};

use crate::config::Config;
use crate::estimator::model::PhotoModel;
use crate::estimator::objects::{Objects, Outcome};
use crate::estimator::realtime::{self, RealtimeSettings};
use crate::estimator::tracking::{Estimate, StreamTracker, TrackState};
use crate::transport::ipc::{send_poses, wake_up, FrameSubscriber, Ipc};
use crate::transport::messages::{
    monotonic_ns, validate_frame, FrameHeader, ObjectName, PoseMsg, PoseSet, Status, FRAMES_SERVICE, MAX_OBJECTS,
    POSES_SERVICE,
};
use crate::vision::lookup::SbsBytes;

use super::skips::FrameSkips;

/// Track the model in the frame stream.
#[derive(clap::Args, Debug)]
pub struct EstimatorArgs {
    /// Photo-model file (from `photopose model`), as `PATH` (the object is named after
    /// the file: `cup.model` → `cup`) or `NAME=PATH`; repeat it to track several objects
    /// (at most 8) on the same frames.
    #[arg(long, value_name = "[NAME=]MODEL", required = true)]
    pub model: Vec<String>,
    /// Configuration file; built-in defaults otherwise.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Stop after this many seconds (0: run until interrupted).
    #[arg(long, default_value_t = 0.0)]
    pub seconds: f64,
}

/// Tracks until `--seconds` pass or a stop is requested, one pose set per processed frame.
pub fn run(args: &EstimatorArgs) -> Result<()> {
    let config = Config::load(args.config.as_deref())?;
    let (mut names, mut models, mut trackers) = (Vec::new(), Vec::new(), Vec::new());
    for (name, path) in parse_models(&args.model)? {
        let model = PhotoModel::load(&path)?;
        trackers.push(StreamTracker::new(model.clone(), config.clone()));
        names.push(name);
        models.push(model);
    }
    let mut objects = Objects::new(trackers);
    apply_realtime(&config.realtime);
    let ipc = Ipc::new("photopose-estimator")?;
    let frames = ipc.frame_subscriber()?;
    let poses = ipc.pose_publisher(POSES_SERVICE)?;
    let (wake, waker) = (ipc.wake(FRAMES_SERVICE)?, ipc.waker(POSES_SERVICE)?);
    let start = Instant::now();
    let mut count = Counts::default();
    let mut last = vec![PoseMsg::none(Status::Searching); names.len()];
    let mut report = Instant::now();
    // Woken by the camera; the timeout only bounds how late a stop request is noticed.
    while ipc.wait_for(&wake, Duration::from_millis(50)) {
        if args.seconds > 0.0 && start.elapsed().as_secs_f64() >= args.seconds {
            break;
        }
        let Some(header) = prepare_newest(&frames, &mut objects, &mut count)? else {
            continue;
        };
        let mut set = PoseSet::default();
        for (k, outcome) in objects.step().into_iter().enumerate() {
            last[k] = match outcome {
                Outcome::Estimate(est) => pose_msg(&models[k], &est, header.frame_id, header.capture_time_ns),
                Outcome::Acquiring => acquiring(&last[k], header.frame_id, header.capture_time_ns),
            };
            set.push(&names[k], last[k])?;
        }
        set.stamp(monotonic_ns());
        send_poses(&poses, &set)?;
        wake_up(&waker);
        count.processed += 1;
        if report.elapsed() >= Duration::from_secs(2) {
            tracing::info!("estimator: frame {}, {}", header.frame_id, count.line(&set));
            report = Instant::now();
        }
    }
    tracing::info!(
        "estimator: {} frames processed, {} dropped, skipped: {}",
        count.processed,
        count.dropped,
        count.skipped.summary()
    );
    Ok(())
}

/// The pose of an object being acquired in the background on frame `frame_id`: its
/// last pose (none yet: [`PoseMsg::none`]) as `searching`, no generations run on this frame.
fn acquiring(last: &PoseMsg, frame_id: u64, capture_time_ns: u64) -> PoseMsg {
    PoseMsg {
        frame_id,
        capture_time_ns,
        generations: 0,
        status: Status::Searching.into(),
        ..*last
    }
}

/// Frames processed, dropped (never seen: a newer one was taken) and skipped (unusable).
#[derive(Default)]
struct Counts {
    processed: u64,
    dropped: u64,
    last_id: Option<u64>,
    skipped: FrameSkips,
}

impl Counts {
    /// Counts the frames between the last one seen and `frame_id` as dropped.
    fn saw(&mut self, frame_id: u64) {
        match self.last_id {
            Some(last) if frame_id > last => self.dropped += frame_id - last - 1,
            Some(_) => tracing::info!("estimator: frame ids restarted at {frame_id}"),
            None => {}
        }
        self.last_id = Some(frame_id);
    }

    /// The progress line: counts, then each object's fitness and status.
    fn line(&self, set: &PoseSet) -> String {
        let objects: Vec<String> = set
            .objects()
            .iter()
            .map(|o| {
                let status = o.pose.status().map_or("?", |s| s.name());
                format!("{} F {:.3} {status}", o.name(), o.pose.fitness)
            })
            .collect();
        format!(
            "{} processed, {} dropped, {}",
            self.processed,
            self.dropped,
            objects.join(", ")
        )
    }
}

/// Takes the newest frame (older queued ones are dropped), checks its header and has
/// every tracker read it while it is held; its header, or `None` when there was no
/// usable frame.
fn prepare_newest(frames: &FrameSubscriber, objects: &mut Objects, count: &mut Counts) -> Result<Option<FrameHeader>> {
    let mut newest = None;
    while let Some(sample) = frames.receive().map_err(|e| anyhow!("cannot receive a frame: {e:?}"))? {
        newest = Some(sample);
    }
    let Some(sample) = newest else { return Ok(None) };
    let header: FrameHeader = *sample.user_header();
    // A header that disagrees with its payload must not steer reads of it.
    let format = match validate_frame(&header, sample.payload().len()) {
        Ok(format) => format,
        Err(fault) => {
            count.skipped.fault(header.frame_id, &fault);
            return Ok(None);
        }
    };
    count.saw(header.frame_id);
    let frame = SbsBytes {
        bytes: sample.payload(),
        width: header.width as usize,
        height: header.height as usize,
        row_stride: header.row_stride as usize,
        format,
    };
    if let Err(e) = objects.prepare(&frame) {
        count.skipped.unusable(header.frame_id, &e);
        return Ok(None);
    }
    Ok(Some(header))
}

/// The objects of `--model` arguments: `PATH` (named after the file stem) or
/// `NAME=PATH`; names must be valid and distinct, and at most [`MAX_OBJECTS`].
pub fn parse_models(args: &[String]) -> Result<Vec<(ObjectName, PathBuf)>> {
    if args.len() > MAX_OBJECTS {
        bail!(
            "{} models given: at most {MAX_OBJECTS} objects can be tracked at once",
            args.len()
        );
    }
    let mut out: Vec<(ObjectName, PathBuf)> = Vec::new();
    for arg in args {
        let (name, path) = match arg.split_once('=') {
            Some((name, path)) => (ObjectName::new(name).map_err(|e| anyhow!("--model {arg}: {e}"))?, path),
            None => {
                let stem = Path::new(arg)
                    .file_stem()
                    .map(|s| s.to_string_lossy())
                    .unwrap_or_default();
                (ObjectName::from_stem(&stem), arg.as_str())
            }
        };
        if out.iter().any(|(n, _)| *n == name) {
            bail!("--model {arg}: the object name {name} is taken; give NAME=PATH");
        }
        out.push((name, PathBuf::from(path)));
    }
    Ok(out)
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

#[cfg(test)]
mod tests {
    use super::*;

    fn names(args: &[&str]) -> Result<Vec<String>> {
        let args: Vec<String> = args.iter().map(|a| a.to_string()).collect();
        Ok(parse_models(&args)?.into_iter().map(|(n, _)| n.to_string()).collect())
    }

    #[test]
    fn objects_are_named_after_their_files_or_as_given() {
        assert_eq!(names(&["models/cup.model", "box=b.model"]).unwrap(), ["cup", "box"]);
        assert_eq!(names(&["a/rocket-v2.model"]).unwrap(), ["rocket_v2"]);
        let twice = names(&["x/cup.model", "y/cup.model"]).unwrap_err().to_string();
        assert!(twice.contains("cup is taken") && twice.contains("NAME=PATH"), "{twice}");
        let bad = names(&["my cup=c.model"]).unwrap_err().to_string();
        assert!(bad.starts_with("--model my cup=c.model: object name"), "{bad}");
        let many: Vec<String> = (0..9).map(|i| format!("m{i}.model")).collect();
        let many: Vec<&str> = many.iter().map(String::as_str).collect();
        assert!(names(&many).unwrap_err().to_string().contains("at most 8"));
    }
}
