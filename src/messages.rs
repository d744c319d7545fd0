//! The messages of DESIGN §4, shared through iceoryx2 by the capture, estimator and
//! client processes (and by C, C++ and Python clients, so the layouts are fixed).

use iceoryx2::prelude::ZeroCopySend;

/// Service carrying side-by-side stereo frames (`[u8]` payload, [`FrameHeader`]).
pub const FRAMES_SERVICE: &str = "photopose/stereo_frames";
/// Service carrying one [`PoseMsg`] per processed frame.
pub const POSES_SERVICE: &str = "photopose/poses";
/// Service carrying the ground-truth [`PoseMsg`] of synthetic and replayed frames.
pub const TRUTH_SERVICE: &str = "photopose/truth";

/// Pixel formats of a frame payload ([`FrameHeader::pixel_format`]).
pub mod pixel_format {
    /// 3 bytes per pixel, R G B.
    pub const RGB8: u32 = 0;
    /// 2 bytes per pixel, Y0 U Y1 V (as the ZED 2i delivers over UVC).
    pub const YUYV: u32 = 1;
}

/// A frame payload's pixel format as a type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PixelFormat {
    Rgb8,
    Yuyv,
}

impl PixelFormat {
    /// The [`pixel_format`] code in frame headers.
    pub fn code(self) -> u32 {
        match self {
            PixelFormat::Rgb8 => pixel_format::RGB8,
            PixelFormat::Yuyv => pixel_format::YUYV,
        }
    }

    pub fn from_code(code: u32) -> Option<Self> {
        match code {
            pixel_format::RGB8 => Some(PixelFormat::Rgb8),
            pixel_format::YUYV => Some(PixelFormat::Yuyv),
            _ => None,
        }
    }

    /// Bytes per pixel.
    pub fn bytes_per_pixel(self) -> usize {
        match self {
            PixelFormat::Rgb8 => 3,
            PixelFormat::Yuyv => 2,
        }
    }

    /// `"RGB8"` or `"YUYV"`, as in files.
    pub fn name(self) -> &'static str {
        match self {
            PixelFormat::Rgb8 => "RGB8",
            PixelFormat::Yuyv => "YUYV",
        }
    }

    /// Parses [`PixelFormat::name`] (case-insensitive).
    pub fn parse(name: &str) -> Option<Self> {
        [PixelFormat::Rgb8, PixelFormat::Yuyv]
            .into_iter()
            .find(|f| f.name().eq_ignore_ascii_case(name.trim()))
    }
}

/// User header of a stereo frame. The payload is the side-by-side image (left eye in the
/// left half), `height` rows of `row_stride` bytes.
#[repr(C)]
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq, ZeroCopySend)]
#[type_name("PhotoposeFrameHeader")]
pub struct FrameHeader {
    /// Increases by one per captured frame, from 0 at capture start.
    pub frame_id: u64,
    /// CLOCK_MONOTONIC when the frame was exposed or received, ns.
    pub capture_time_ns: u64,
    /// Size of one eye, pixels.
    pub width: u32,
    pub height: u32,
    /// One of [`pixel_format`].
    pub pixel_format: u32,
    /// Bytes per row of the side-by-side image.
    pub row_stride: u32,
    /// CLOCK_MONOTONIC just before the frame was sent, ns (transport latency).
    pub publish_time_ns: u64,
}

/// Tracking status of a [`PoseMsg`].
pub mod status {
    /// The object is tracked; the pose is current.
    pub const TRACKING: u32 = 0;
    /// The estimator is (re)acquiring; the pose is the best guess so far.
    pub const SEARCHING: u32 = 1;
    /// Nothing matches; do not act on the pose.
    pub const LOST: u32 = 2;
}

/// One pose of the model in the hand frame (DESIGN §4, type name `PhotoposePose`).
#[repr(C)]
#[derive(Debug, Default, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("PhotoposePose")]
pub struct PoseMsg {
    pub frame_id: u64,
    /// CLOCK_MONOTONIC when the frame was exposed or received, ns.
    pub capture_time_ns: u64,
    /// CLOCK_MONOTONIC when this pose was published, ns.
    pub publish_time_ns: u64,
    /// Model origin in the hand frame.
    pub position_mm: [f64; 3],
    /// Model rotation in the hand frame.
    pub orientation_wxyz: [f64; 4],
    /// L (model x extent), B (model y extent).
    pub size_mm: [f64; 2],
    /// F of the best individual, 0..2.
    pub fitness: f64,
    /// GA generations run on this frame.
    pub generations: u32,
    /// One of [`status`].
    pub status: u32,
}

/// CLOCK_MONOTONIC now, ns: the time base of every timestamp in the messages.
pub fn monotonic_ns() -> u64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: `ts` is a valid, writable timespec; CLOCK_MONOTONIC always exists on Linux.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::mem::{align_of, offset_of, size_of};

    #[test]
    fn pose_layout_is_the_contract() {
        assert_eq!(size_of::<PoseMsg>(), 112);
        assert_eq!(align_of::<PoseMsg>(), 8);
        let offsets = [
            offset_of!(PoseMsg, frame_id),
            offset_of!(PoseMsg, capture_time_ns),
            offset_of!(PoseMsg, publish_time_ns),
            offset_of!(PoseMsg, position_mm),
            offset_of!(PoseMsg, orientation_wxyz),
            offset_of!(PoseMsg, size_mm),
            offset_of!(PoseMsg, fitness),
            offset_of!(PoseMsg, generations),
            offset_of!(PoseMsg, status),
        ];
        assert_eq!(offsets, [0, 8, 16, 24, 48, 80, 96, 104, 108]);
    }

    #[test]
    fn frame_header_layout_is_fixed() {
        assert_eq!(size_of::<FrameHeader>(), 40);
        assert_eq!(align_of::<FrameHeader>(), 8);
        let offsets = [
            offset_of!(FrameHeader, frame_id),
            offset_of!(FrameHeader, capture_time_ns),
            offset_of!(FrameHeader, width),
            offset_of!(FrameHeader, height),
            offset_of!(FrameHeader, pixel_format),
            offset_of!(FrameHeader, row_stride),
            offset_of!(FrameHeader, publish_time_ns),
        ];
        assert_eq!(offsets, [0, 8, 16, 20, 24, 28, 32]);
    }

    #[test]
    fn type_names_are_the_contract() {
        use iceoryx2::prelude::ZeroCopySend;
        // SAFETY: `type_name` only reads the name the derive stored.
        assert_eq!(unsafe { <PoseMsg as ZeroCopySend>::type_name() }, "PhotoposePose");
        assert_eq!(
            unsafe { <FrameHeader as ZeroCopySend>::type_name() },
            "PhotoposeFrameHeader"
        );
    }

    #[test]
    fn monotonic_clock_advances() {
        let a = monotonic_ns();
        std::thread::sleep(std::time::Duration::from_millis(2));
        let b = monotonic_ns();
        assert!(b >= a + 1_000_000, "{a} {b}");
    }
}
