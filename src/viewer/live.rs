//! `photopose viewer`'s loop. Woken when the estimator has published a pose (so its
//! work falls in the estimator's idle time between frames), it logs the figures of every
//! pose and truth that arrived; at its own pace (10–15 Hz) it also takes the newest frame
//! of `photopose/stereo_frames`, shrinks and compresses the left eye and logs it with the
//! newest poses' card and outline. It holds no frame longer than the shrinking of one eye
//! and runs in the idle scheduling class, so it never slows the estimator; frames it does
//! not take are simply overwritten.

use std::time::{Duration, Instant};

use anyhow::{anyhow, Result};
use rerun::RecordingStream;

use crate::camera::calibration::Calibration;
use crate::camera::Intrinsics;
use crate::transport::ipc::{receive_poses, FrameSubscriber, Ipc, PoseSubscriber};
use crate::transport::messages::{validate_frame, PoseMsg, POSES_SERVICE, TRUTH_SERVICE};
use crate::viewer::outline::{status_colour, TRUTH_COLOUR};
use crate::viewer::scene::{self, Drawing, Kind};
use crate::viewer::thumbnail;
use crate::vision::lookup::SbsBytes;

/// How the service is followed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Options {
    /// Images per second at most.
    pub rate_hz: f64,
    /// Widest logged image, pixels.
    pub max_width: usize,
    /// JPEG quality, 1–100.
    pub quality: u8,
    /// The model's outer strip width over its length L (0: draw no strip).
    pub strip_per_length: f64,
    /// Stop after this many seconds (0: until interrupted).
    pub seconds: f64,
}

/// The shortest wait (a zero timeout would not sleep).
const MIN_WAIT: Duration = Duration::from_millis(1);
/// Positions kept in each trajectory line.
const TRAIL: usize = 600;
/// The estimated trajectory's colour (the truth's is [`TRUTH_COLOUR`]).
const ESTIMATE_TRAIL: [u8; 3] = [255, 150, 40];

/// What was logged.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct Counts {
    /// Images.
    pub frames: u64,
    /// Estimated poses.
    pub poses: u64,
    /// Truths.
    pub truths: u64,
}

/// Puts this thread, and the threads it starts later, in the idle scheduling class
/// (`SCHED_IDLE`; nice 19 where that is refused): they run only on cores nothing else
/// wants, and any other task that wakes preempts them at once, so the estimator never
/// waits for the viewer.
pub fn lower_priority() {
    let param = libc::sched_param { sched_priority: 0 };
    // SAFETY: sched_setscheduler(2) and setpriority(2) on the calling thread only change
    // its scheduling; `param` outlives the call.
    let idle = unsafe { libc::sched_setscheduler(0, libc::SCHED_IDLE, &param) } == 0;
    if !idle && unsafe { libc::setpriority(libc::PRIO_PROCESS, 0, 19) } != 0 {
        tracing::debug!("viewer: cannot lower the priority: {}", std::io::Error::last_os_error());
    }
}

impl Options {
    /// The first option that cannot be used, as an error.
    pub fn check(&self) -> Result<()> {
        if !(self.rate_hz.is_finite() && self.rate_hz > 0.0) {
            return Err(anyhow!("--rate {} must be a positive number", self.rate_hz));
        }
        if self.max_width < 16 {
            return Err(anyhow!("--width {} must be at least 16 pixels", self.max_width));
        }
        Ok(())
    }
}

/// Logs the service to `rec` until interrupted or `options.seconds` pass.
pub fn run(
    rec: &RecordingStream,
    calibration: &Calibration,
    left_from_hand: &nalgebra::Isometry3<f64>,
    options: &Options,
) -> Result<Counts> {
    let ipc = Ipc::new("photopose-viewer")?;
    let frames = ipc.frame_subscriber()?;
    let poses = ipc.pose_subscriber(POSES_SERVICE)?;
    let truths = ipc.pose_subscriber(TRUTH_SERVICE)?;
    let mut live = Live {
        rec,
        calibration,
        left_from_hand,
        options,
        camera: None,
        trails: [Vec::new(), Vec::new()],
        newest: [None, None],
        last_frame: None,
        dropped: 0,
        counts: Counts::default(),
    };
    let period = Duration::from_secs_f64(1.0 / options.rate_hz);
    let start = Instant::now();
    let mut due = start;
    // It sleeps until the next image is due and then takes every pose that came
    // meanwhile (the subscribers hold about a second of them): it never listens for
    // the estimator's wake-ups, which would add a listener to every pose it sends.
    while ipc.wait(due.saturating_duration_since(Instant::now()).max(MIN_WAIT)) {
        if options.seconds > 0.0 && start.elapsed().as_secs_f64() >= options.seconds {
            break;
        }
        let now = Instant::now();
        if now < due {
            continue;
        }
        due = (due + period).max(now);
        live.poses(&truths, Kind::Truth)?;
        live.poses(&poses, Kind::Estimate)?;
        live.frame(&frames)?;
        live.draw_newest()?;
    }
    Ok(live.counts)
}

/// The loop's state.
struct Live<'a> {
    rec: &'a RecordingStream,
    calibration: &'a Calibration,
    left_from_hand: &'a nalgebra::Isometry3<f64>,
    options: &'a Options,
    /// The eye size the camera was logged for, and the logged image's camera.
    camera: Option<((u32, u32), Option<Intrinsics>)>,
    /// Estimate and truth positions, newest last.
    trails: [Vec<[f32; 3]>; 2],
    /// The newest estimate and truth not drawn yet.
    newest: [Option<PoseMsg>; 2],
    /// The last estimated pose's frame, for the drop count.
    last_frame: Option<u64>,
    dropped: u64,
    counts: Counts,
}

impl Live<'_> {
    /// Logs the newest frame, if a new one came.
    fn frame(&mut self, frames: &FrameSubscriber) -> Result<()> {
        let mut newest = None;
        while let Some(sample) = frames.receive().map_err(|e| anyhow!("cannot receive a frame: {e:?}"))? {
            newest = Some(sample);
        }
        let Some(sample) = newest else { return Ok(()) };
        let header = *sample.user_header();
        let format = match validate_frame(&header, sample.payload().len()) {
            Ok(format) => format,
            Err(fault) => {
                tracing::debug!("viewer: frame {} skipped: {fault}", header.frame_id);
                return Ok(());
            }
        };
        let (width, height) = (header.width as usize, header.height as usize);
        let step = thumbnail::factor(width, self.options.max_width, format);
        let sbs = SbsBytes {
            bytes: sample.payload(),
            width,
            height,
            row_stride: header.row_stride as usize,
            format,
        };
        let start = Instant::now();
        let Some(image) = thumbnail::left_eye(&sbs, step) else {
            return Ok(());
        };
        drop(sample);
        let shrunk = start.elapsed();
        self.camera_for((header.width, header.height), step, image.dimensions())?;
        let jpeg = scene::jpeg(&image, self.options.quality)?;
        let encoded = start.elapsed();
        scene::set_frame_time(self.rec, header.frame_id, header.capture_time_ns);
        self.rec.log(scene::IMAGE, &jpeg)?;
        tracing::debug!(
            "viewer: frame {} shrunk in {:.1} ms, compressed in {:.1} ms, logged in {:.1} ms",
            header.frame_id,
            shrunk.as_secs_f64() * 1e3,
            (encoded - shrunk).as_secs_f64() * 1e3,
            (start.elapsed() - encoded).as_secs_f64() * 1e3
        );
        self.counts.frames += 1;
        Ok(())
    }

    /// Logs the camera when the eye size is new: the calibration's camera for that size,
    /// scaled to the logged image.
    fn camera_for(&mut self, eye: (u32, u32), step: usize, logged: (u32, u32)) -> Result<()> {
        if self.camera.as_ref().is_some_and(|(size, _)| *size == eye) {
            return Ok(());
        }
        let camera = match self.calibration.rig_for_image(eye.0, eye.1) {
            Ok(rig) => Some(rig.left.scaled(1.0 / step as f64)),
            Err(e) => {
                tracing::warn!("viewer: no outline or camera: {e}");
                None
            }
        };
        if let Some(c) = &camera {
            scene::log_camera(self.rec, self.left_from_hand, c, logged)?;
        }
        self.camera = Some((eye, camera));
        Ok(())
    }

    /// Logs the figures of every pose of the first object that arrived on `subscriber`
    /// as `kind`.
    fn poses(&mut self, subscriber: &PoseSubscriber, kind: Kind) -> Result<()> {
        while let Some(set) = receive_poses(subscriber)? {
            let Some(&p) = set.first() else { continue };
            if p.is_sound() {
                self.pose(&p, kind)?;
                self.newest[usize::from(kind == Kind::Truth)] = Some(p);
            }
        }
        Ok(())
    }

    /// Logs the card, outline and trajectory of the newest estimate and truth at their
    /// frames (at the viewer's pace, as the images are).
    fn draw_newest(&mut self) -> Result<()> {
        for kind in [Kind::Estimate, Kind::Truth] {
            if let Some(p) = self.newest[usize::from(kind == Kind::Truth)].take() {
                self.draw(&p, kind)?;
            }
        }
        Ok(())
    }

    /// Logs the card, outline and trajectory of `p` at its frame.
    fn draw(&self, p: &PoseMsg, kind: Kind) -> Result<()> {
        scene::set_frame_time(self.rec, p.frame_id, p.capture_time_ns);
        let (trail, trail_colour, colour) = match kind {
            Kind::Estimate => (&self.trails[0], ESTIMATE_TRAIL, status_colour(p.status)),
            Kind::Truth => (&self.trails[1], TRUTH_COLOUR, TRUTH_COLOUR),
        };
        let drawing = Drawing {
            colour,
            strip_per_length: self.options.strip_per_length,
            left_from_hand: self.left_from_hand,
            camera: self.camera.and_then(|(_, c)| c),
        };
        scene::log_pose(self.rec, kind, p, &drawing)?;
        scene::log_trajectory(self.rec, kind, trail, trail_colour)?;
        Ok(())
    }

    /// Logs one pose's figures at its frame's time.
    fn pose(&mut self, p: &PoseMsg, kind: Kind) -> Result<()> {
        let rec = self.rec;
        scene::set_frame_time(rec, p.frame_id, p.capture_time_ns);
        scene::log_position(rec, kind, p)?;
        let trail = &mut self.trails[usize::from(kind == Kind::Truth)];
        trail.push(p.position_mm.map(|v| v as f32));
        if trail.len() > TRAIL {
            trail.remove(0);
        }
        match kind {
            Kind::Truth => self.counts.truths += 1,
            Kind::Estimate => {
                self.counts.poses += 1;
                self.estimate_series(p)?;
            }
        }
        Ok(())
    }

    /// Fitness, status, capture → pose latency and frames dropped so far.
    fn estimate_series(&mut self, p: &PoseMsg) -> Result<()> {
        if let Some(last) = self.last_frame.filter(|&l| p.frame_id > l) {
            self.dropped += p.frame_id - last - 1;
        }
        self.last_frame = Some(p.frame_id);
        let latency_ms = p.publish_time_ns.saturating_sub(p.capture_time_ns) as f64 * 1e-6;
        for (path, v) in [
            ("series/fitness", p.fitness),
            ("series/status", f64::from(p.status)),
            ("series/latency_ms", latency_ms),
            ("series/dropped", self.dropped as f64),
        ] {
            scene::scalar(self.rec, path, v)?;
        }
        Ok(())
    }
}
