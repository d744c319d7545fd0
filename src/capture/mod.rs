//! The capture side: frame sources for the capture process, the recorded-sequence
//! format, and recording.
//!
//! A [`FrameSource`] writes each side-by-side frame straight into the buffer it is
//! given (a sample loaned from the iceoryx2 publisher, not zeroed first: see
//! [`frame_buf`]), so publishing a frame costs no allocation and no extra copy. Sources
//! now:
//! - `synthetic[:SCENE.toml]` ([`synthetic`]): the synthetic camera, its card moving
//!   along a scripted loop, with each frame's ground truth;
//! - `replay:DIR` ([`replay`]): a recorded [`sequence`], at its recorded or a fixed rate;
//! - `zed` ([`zed`]): a ZED 2i over V4L2 (cargo feature `zed`).

pub mod frame_buf;
pub mod record;
pub mod replay;
pub mod scenario;
pub mod sequence;
pub mod synthetic;
pub mod zed;

use std::path::PathBuf;
use std::time::Instant;

use nalgebra::Isometry3;

use crate::estimator::pose::PoseSize;
use crate::transport::messages::{ObjectName, PoseMsg, PoseSet, Status, MAX_OBJECTS};
use crate::vision::PixelFormat;

pub use frame_buf::{FrameBuf, Written};

/// Where frames come from.
#[derive(Debug, Clone, PartialEq)]
pub enum Source {
    /// The synthetic camera rendering a scene file.
    Synthetic(PathBuf),
    /// A recorded sequence directory.
    Replay(PathBuf),
    /// A ZED camera over V4L2.
    Zed,
}

/// Scene of `synthetic` without a file name.
pub const DEFAULT_SCENE: &str = "config/scenes/rocket.toml";

impl Source {
    /// Parses `synthetic`, `synthetic:SCENE.toml`, `replay:DIR` or `zed`.
    pub fn parse(s: &str) -> Result<Self, SourceError> {
        if s == "zed" {
            return Ok(Source::Zed);
        }
        match s.split_once(':') {
            None if s == "synthetic" => Ok(Source::Synthetic(PathBuf::from(DEFAULT_SCENE))),
            Some(("synthetic", scene)) if !scene.is_empty() => Ok(Source::Synthetic(PathBuf::from(scene))),
            Some(("replay", dir)) if !dir.is_empty() => Ok(Source::Replay(PathBuf::from(dir))),
            _ => Err(SourceError::Unknown(s.to_string())),
        }
    }
}

/// A frame source that cannot deliver.
#[derive(Debug, thiserror::Error)]
pub enum SourceError {
    /// `--source` names no source photopose has.
    #[error("unknown source {0:?}: use synthetic[:SCENE.toml], replay:DIR or zed")]
    Unknown(String),
    /// A recording's description or frame list cannot be read.
    #[error(transparent)]
    Sequence(#[from] sequence::SequenceError),
    /// A recorded frame file cannot be read or has the wrong size.
    #[error("{path}: {message}")]
    Frame {
        /// The frame file.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
    /// The source cannot start (scene, calibration or camera), in words.
    #[error("{0}")]
    Setup(String),
    /// The buffer lent for a frame is not the frame's size.
    #[error("a {buffer}-byte buffer cannot hold a {frame}-byte frame")]
    BufferSize {
        /// Bytes lent.
        buffer: usize,
        /// Bytes of the source's frame.
        frame: usize,
    },
}

/// Layout of the side-by-side frames of a source.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Geometry {
    /// Size of one eye, pixels.
    pub width: u32,
    /// Height of each eye and of the side-by-side frame, pixels.
    pub height: u32,
    /// How each pixel is stored.
    pub format: PixelFormat,
}

impl Geometry {
    /// Bytes per row of the side-by-side image (rows are packed).
    pub fn row_stride(&self) -> usize {
        2 * self.width as usize * self.format.bytes_per_pixel()
    }

    /// Bytes of one side-by-side frame.
    pub fn frame_len(&self) -> usize {
        self.row_stride() * self.height as usize
    }
}

/// The true pose and size of the target in a frame (hand frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Truth {
    /// Pose of the target's model frame in the hand frame, mm.
    pub hand_from_model: Isometry3<f64>,
    /// Length and breadth of the target, mm.
    pub size_mm: [f64; 2],
}

impl Truth {
    /// The truth as a pose message of frame `frame_id`.
    pub fn pose_msg(&self, frame_id: u64, capture_time_ns: u64) -> PoseMsg {
        let p = PoseSize::from_pose(&self.hand_from_model, self.size_mm, self.size_mm[0], self.size_mm[1]);
        PoseMsg {
            frame_id,
            capture_time_ns,
            publish_time_ns: 0,
            position_mm: p.position.into(),
            orientation_wxyz: p.orientation_wxyz(),
            size_mm: self.size_mm,
            fitness: 0.0,
            generations: 0,
            status: Status::Tracking.into(),
        }
    }
}

/// What a source knows about the frame it just wrote.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameInfo {
    /// CLOCK_MONOTONIC when the frame was taken, ns.
    pub capture_time_ns: u64,
    /// The true pose and size of each object of [`FrameSource::objects`] in this frame,
    /// where the source knows it (the first is the one a recording keeps).
    pub truth: [Option<Truth>; MAX_OBJECTS],
    /// The source's own number for the frame, published instead of the capture's count:
    /// a replay's recorded `frame_id`.
    pub frame_id: Option<u64>,
}

impl FrameInfo {
    /// A frame taken at `capture_time_ns` with (at most) one object's truth.
    pub fn single(capture_time_ns: u64, truth: Option<Truth>) -> Self {
        let mut all = [None; MAX_OBJECTS];
        all[0] = truth;
        Self {
            capture_time_ns,
            truth: all,
            frame_id: None,
        }
    }

    /// The known truths as the pose set of frame `frame_id`, named after `names`.
    pub fn truth_set(&self, names: &[ObjectName], frame_id: u64) -> PoseSet {
        let mut set = PoseSet::default();
        for (name, truth) in names.iter().zip(&self.truth) {
            if let Some(t) = truth {
                // Cannot fail: `truth` has no more entries than a set has room for.
                let _ = set.push(name, t.pose_msg(frame_id, self.capture_time_ns));
            }
        }
        set
    }
}

/// The name of a source's only object when it has no better one (replays, cameras).
pub const TARGET: &str = "target";

/// A camera-like source of side-by-side frames.
pub trait FrameSource {
    /// Layout of every frame this source writes.
    fn geometry(&self) -> Geometry;

    /// One line for logs: what is being captured.
    fn describe(&self) -> String;

    /// The names of the objects whose truth [`FrameInfo::truth`] carries, in its order.
    fn objects(&self) -> Vec<ObjectName> {
        vec![ObjectName::from_stem(TARGET)]
    }

    /// When the next frame is due; `None` once the stream has ended.
    fn next_due(&mut self) -> Option<Instant>;

    /// Writes the due frame into `buf` ([`Geometry::frame_len`] bytes, possibly
    /// uninitialised), handing back the proof that every byte was written; `Ok(None)`
    /// when no frame came this time (the caller asks again).
    fn write_frame<'a>(&mut self, buf: FrameBuf<'a>) -> Result<Option<(FrameInfo, Written<'a>)>, SourceError>;

    /// [`FrameSource::write_frame`] into an initialised buffer, e.g. one `Vec` reused
    /// for every frame.
    fn fill(&mut self, buf: &mut [u8]) -> Result<Option<FrameInfo>, SourceError> {
        Ok(self.write_frame(FrameBuf::from_init(buf))?.map(|(info, _)| info))
    }

    /// One line for the log when capture ends (counters of faults), if the source has one.
    fn summary(&self) -> Option<String> {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sources_parse_or_explain() {
        assert_eq!(
            Source::parse("synthetic").unwrap(),
            Source::Synthetic(PathBuf::from(DEFAULT_SCENE))
        );
        assert_eq!(
            Source::parse("synthetic:a/b.toml").unwrap(),
            Source::Synthetic(PathBuf::from("a/b.toml"))
        );
        assert_eq!(
            Source::parse("replay:rec/run1").unwrap(),
            Source::Replay(PathBuf::from("rec/run1"))
        );
        assert_eq!(Source::parse("zed").unwrap(), Source::Zed);
        for bad in ["webcam", "replay:", "synthetic:", "zed:0"] {
            let e = Source::parse(bad).unwrap_err().to_string();
            assert!(
                e.contains(bad) && e.contains("synthetic") && e.contains("replay") && e.contains("zed"),
                "{e}"
            );
        }
    }

    #[test]
    fn geometry_counts_bytes_per_format() {
        let rgb = Geometry {
            width: 1280,
            height: 720,
            format: PixelFormat::Rgb8,
        };
        assert_eq!((rgb.row_stride(), rgb.frame_len()), (7680, 7680 * 720));
        let yuyv = Geometry {
            format: PixelFormat::Yuyv,
            ..rgb
        };
        assert_eq!((yuyv.row_stride(), yuyv.frame_len()), (5120, 5120 * 720));
    }
}
