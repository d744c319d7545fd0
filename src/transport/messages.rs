//! The messages of DESIGN §4, shared through iceoryx2 by the capture, estimator and
//! client processes (and by C, C++ and Python clients, so the layouts are fixed).

use iceoryx2::prelude::ZeroCopySend;

use crate::camera::geometry::{is_unit_wxyz, w_nonnegative, wxyz_norm};
use crate::vision::PixelFormat;

/// Service carrying side-by-side stereo frames (`[u8]` payload, [`FrameHeader`]).
pub const FRAMES_SERVICE: &str = "photopose/stereo_frames";
/// Service carrying one [`PoseSet`] per processed frame: every tracked object's pose.
pub const POSES_SERVICE: &str = "photopose/poses";
/// Service carrying the ground-truth [`PoseSet`] of synthetic and replayed frames.
pub const TRUTH_SERVICE: &str = "photopose/truth";

/// Pixel formats of a frame payload ([`FrameHeader::pixel_format`]).
pub mod pixel_format {
    /// 3 bytes per pixel, R G B.
    pub const RGB8: u32 = 0;
    /// 2 bytes per pixel, Y0 U Y1 V (as the ZED 2i delivers over UVC).
    pub const YUYV: u32 = 1;
}

/// The wire codes of [`PixelFormat`] (the type lives with the image data).
impl PixelFormat {
    /// The [`pixel_format`] code in frame headers.
    pub fn code(self) -> u32 {
        match self {
            PixelFormat::Rgb8 => pixel_format::RGB8,
            PixelFormat::Yuyv => pixel_format::YUYV,
        }
    }

    /// The format of a header's [`pixel_format`] code, `None` for an unknown one.
    pub fn from_code(code: u32) -> Option<Self> {
        match code {
            pixel_format::RGB8 => Some(PixelFormat::Rgb8),
            pixel_format::YUYV => Some(PixelFormat::Yuyv),
            _ => None,
        }
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
    /// Width of one eye, pixels (the side-by-side image is twice as wide).
    pub width: u32,
    /// Height of one eye and of the side-by-side image, pixels.
    pub height: u32,
    /// One of [`pixel_format`].
    pub pixel_format: u32,
    /// Bytes per row of the side-by-side image.
    pub row_stride: u32,
    /// CLOCK_MONOTONIC just before the frame was sent, ns (transport latency).
    pub publish_time_ns: u64,
}

/// Why a received frame cannot be used: its header disagrees with its payload.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum FrameFault {
    /// The header's `pixel_format` is not one of [`pixel_format`].
    #[error("unknown pixel format code {code}")]
    UnknownPixelFormat {
        /// The header's `pixel_format` code.
        code: u32,
    },
    /// The header's width or height is zero.
    #[error("empty image ({width}x{height} per eye)")]
    Empty {
        /// Width of one eye, pixels.
        width: u32,
        /// Height of one eye, pixels.
        height: u32,
    },
    /// A YUYV frame's eye width is odd.
    #[error("YUYV eye width {width} is odd (YUYV pixels come in pairs)")]
    OddYuyvWidth {
        /// Width of one eye, pixels.
        width: u32,
    },
    /// The row stride cannot hold both eyes' pixels of one row.
    #[error("row stride {stride} is shorter than a side-by-side row of {row} bytes")]
    StrideTooShort {
        /// The header's row stride, bytes.
        stride: u32,
        /// Bytes of both eyes' pixels in one row.
        row: u64,
    },
    /// The payload is not exactly `height · row_stride` bytes.
    #[error("payload of {len} bytes, but the header says {expected} ({height} rows of {stride} bytes)")]
    LengthMismatch {
        /// Payload size received, bytes.
        len: usize,
        /// Payload size the header implies, bytes.
        expected: u64,
        /// The header's height, rows.
        height: u32,
        /// The header's row stride, bytes.
        stride: u32,
    },
}

impl FrameFault {
    /// Every kind, in the order of [`FrameFault::index`].
    pub const KINDS: [&'static str; 5] = [
        "unknown pixel format",
        "empty image",
        "odd YUYV width",
        "short stride",
        "wrong length",
    ];

    /// A stable index per kind (for counting).
    pub fn index(&self) -> usize {
        match self {
            FrameFault::UnknownPixelFormat { .. } => 0,
            FrameFault::Empty { .. } => 1,
            FrameFault::OddYuyvWidth { .. } => 2,
            FrameFault::StrideTooShort { .. } => 3,
            FrameFault::LengthMismatch { .. } => 4,
        }
    }
}

/// Checks a received frame's header against its payload: a known pixel format, a
/// non-empty image (of whole pixel pairs per YUYV eye), a row stride that holds both eyes' pixels
/// (`2 · width · bytes per pixel`), and exactly `height · row_stride` payload bytes.
/// Only a frame that passes may be read with the header's geometry.
pub fn validate_frame(header: &FrameHeader, payload_len: usize) -> Result<PixelFormat, FrameFault> {
    let format = PixelFormat::from_code(header.pixel_format).ok_or(FrameFault::UnknownPixelFormat {
        code: header.pixel_format,
    })?;
    let (width, height, stride) = (header.width, header.height, header.row_stride);
    if width == 0 || height == 0 {
        return Err(FrameFault::Empty { width, height });
    }
    if format == PixelFormat::Yuyv && width % 2 != 0 {
        return Err(FrameFault::OddYuyvWidth { width });
    }
    // u64: no header can overflow these.
    let row = 2 * width as u64 * format.bytes_per_pixel() as u64;
    if (stride as u64) < row {
        return Err(FrameFault::StrideTooShort { stride, row });
    }
    let expected = height as u64 * stride as u64;
    if payload_len as u64 != expected {
        return Err(FrameFault::LengthMismatch {
            len: payload_len,
            expected,
            height,
            stride,
        });
    }
    Ok(format)
}

/// Tracking status of a [`PoseMsg`]: its `status` field on the wire.
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Status {
    /// The object is tracked; the pose is current.
    Tracking = 0,
    /// The estimator is (re)acquiring, or follows an object whose tilt the stereo pair
    /// cannot resolve; the pose is the best guess so far.
    Searching = 1,
    /// Nothing matches; do not act on the pose.
    Lost = 2,
}

impl Status {
    /// `"tracking"`, `"searching"` or `"lost"`.
    pub fn name(self) -> &'static str {
        match self {
            Status::Tracking => "tracking",
            Status::Searching => "searching",
            Status::Lost => "lost",
        }
    }
}

/// A `status` code that is not a [`Status`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("unknown status code {0}")]
pub struct UnknownStatus(pub u32);

impl TryFrom<u32> for Status {
    type Error = UnknownStatus;

    fn try_from(code: u32) -> Result<Self, UnknownStatus> {
        [Status::Tracking, Status::Searching, Status::Lost]
            .into_iter()
            .find(|s| *s as u32 == code)
            .ok_or(UnknownStatus(code))
    }
}

impl From<Status> for u32 {
    fn from(status: Status) -> u32 {
        status as u32
    }
}

/// One pose of a model in the hand frame: the record of DESIGN §4 (type name
/// `PhotoposePose`, 112 bytes). Since the wire contract's version 2 it travels inside a
/// [`PoseSet`], once per object; no service carries it alone any more.
#[repr(C)]
#[derive(Debug, Default, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("PhotoposePose")]
pub struct PoseMsg {
    /// [`FrameHeader::frame_id`] of the frame the pose was estimated from.
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
    /// A [`Status`] code.
    pub status: u32,
}

/// Largest deviation of a published quaternion's norm from 1.
pub const UNIT_TOLERANCE: f64 = 1e-9;

impl PoseMsg {
    /// The pose's [`Status`], or the unknown code.
    pub fn status(&self) -> Result<Status, UnknownStatus> {
        Status::try_from(self.status)
    }

    /// Every number finite, a known status, and a unit orientation quaternion with
    /// `w ≥ 0`: the only poses photopose publishes.
    pub fn is_sound(&self) -> bool {
        let q = self.orientation_wxyz;
        self.position_mm
            .iter()
            .chain(&self.size_mm)
            .chain(&q)
            .chain([&self.fitness])
            .all(|v| v.is_finite())
            && is_unit_wxyz(q, UNIT_TOLERANCE)
            && q[0] >= 0.0
            && self.status().is_ok()
    }

    /// Makes the pose sound: normalises the quaternion to `w ≥ 0`. A pose with a NaN or
    /// infinite number, a zero quaternion or an unknown status cannot be repaired: it
    /// becomes `lost` at the origin with the identity rotation, zero size and fitness 0.
    pub fn sanitize(&mut self) {
        let q = self.orientation_wxyz;
        let norm = wxyz_norm(q);
        if norm.is_finite() && norm > 0.0 {
            self.orientation_wxyz = w_nonnegative(q.map(|v| v / norm));
        }
        if !self.is_sound() {
            *self = PoseMsg {
                frame_id: self.frame_id,
                capture_time_ns: self.capture_time_ns,
                publish_time_ns: self.publish_time_ns,
                generations: self.generations,
                ..PoseMsg::none(Status::Lost)
            };
        }
    }

    /// No pose known, as `status`: the origin with the identity rotation, zero size and
    /// fitness 0, a sound pose that must not be acted on.
    pub fn none(status: Status) -> Self {
        PoseMsg {
            orientation_wxyz: [1.0, 0.0, 0.0, 0.0],
            status: status as u32,
            ..PoseMsg::default()
        }
    }
}

/// Objects one [`PoseSet`] carries at most.
pub const MAX_OBJECTS: usize = 8;
/// Bytes of an [`ObjectPose::name`]: up to 31 of UTF-8, then NUL padding.
pub const NAME_LEN: usize = 32;

/// One object's pose in a [`PoseSet`]: its name and its [`PoseMsg`] (144 bytes).
#[repr(C)]
#[derive(Debug, Default, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("PhotoposeObjectPose")]
pub struct ObjectPose {
    /// The object's name ([`ObjectName`]), NUL-padded.
    pub name: [u8; NAME_LEN],
    /// Its pose in the frame.
    pub pose: PoseMsg,
}

impl ObjectPose {
    /// The name up to its first NUL (`"?"` if those bytes are not UTF-8).
    pub fn name(&self) -> &str {
        let end = self.name.iter().position(|&b| b == 0).unwrap_or(NAME_LEN);
        std::str::from_utf8(&self.name[..end]).unwrap_or("?")
    }
}

/// The poses of every object in one frame, published together: the payload of
/// `photopose/poses` and `photopose/truth` since version 2 of the wire contract (type
/// name `PhotoposePoseV2`, 1160 bytes). A client built for version 1 (`PhotoposePose`)
/// fails to open the service with a type error instead of misreading these bytes.
#[repr(C)]
#[derive(Debug, Default, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("PhotoposePoseV2")]
pub struct PoseSet {
    /// Objects in use, `objects[..count]` (at most [`MAX_OBJECTS`]).
    pub count: u32,
    /// Zero; keeps `objects` 8-byte aligned.
    pub reserved: u32,
    /// The objects' poses, in the estimator's order; the rest zero.
    pub objects: [ObjectPose; MAX_OBJECTS],
}

/// A [`PoseSet`] already holds [`MAX_OBJECTS`] objects.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("a pose set holds at most {MAX_OBJECTS} objects")]
pub struct SetFull;

impl PoseSet {
    /// A set of one object's pose.
    pub fn single(name: &ObjectName, pose: PoseMsg) -> Self {
        let mut set = PoseSet::default();
        set.objects[0] = ObjectPose {
            name: name.bytes(),
            pose,
        };
        set.count = 1;
        set
    }

    /// Appends an object's pose.
    pub fn push(&mut self, name: &ObjectName, pose: PoseMsg) -> Result<(), SetFull> {
        let slot = self.objects.get_mut(self.count as usize).ok_or(SetFull)?;
        *slot = ObjectPose {
            name: name.bytes(),
            pose,
        };
        self.count += 1;
        Ok(())
    }

    /// The objects in use (a `count` beyond [`MAX_OBJECTS`] is read as the maximum).
    pub fn objects(&self) -> &[ObjectPose] {
        &self.objects[..(self.count as usize).min(MAX_OBJECTS)]
    }

    /// The pose of the object named `name`.
    pub fn get(&self, name: &str) -> Option<&PoseMsg> {
        self.objects().iter().find(|o| o.name() == name).map(|o| &o.pose)
    }

    /// The first object's pose (the only one of a single-object estimator).
    pub fn first(&self) -> Option<&PoseMsg> {
        self.objects().first().map(|o| &o.pose)
    }

    /// Sets every object's publish time.
    pub fn stamp(&mut self, publish_time_ns: u64) {
        let n = self.objects().len();
        for o in &mut self.objects[..n] {
            o.pose.publish_time_ns = publish_time_ns;
        }
    }
}

/// An object's name: 1–31 ASCII letters, digits or underscores, starting with a letter,
/// so it is also a valid ROS 2 topic name component (`/photopose/<name>/pose`).
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ObjectName(String);

impl ObjectName {
    /// Checks `name`; the error says what is wrong with it.
    pub fn new(name: &str) -> Result<Self, String> {
        let mut chars = name.chars();
        if !chars.next().is_some_and(|c| c.is_ascii_alphabetic()) {
            return Err(format!("object name {name:?} must start with an ASCII letter"));
        }
        if !chars.all(|c| c.is_ascii_alphanumeric() || c == '_') {
            return Err(format!(
                "object name {name:?} may hold only ASCII letters, digits and underscores"
            ));
        }
        if name.len() >= NAME_LEN {
            return Err(format!("object name {name:?} is longer than {} bytes", NAME_LEN - 1));
        }
        Ok(Self(name.to_string()))
    }

    /// A valid name made from a file stem: other characters become `_`, a leading
    /// non-letter gets an `o` in front, and it is cut to 31 bytes (`"object"` if empty).
    pub fn from_stem(stem: &str) -> Self {
        let mut name: String = stem
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
            .collect();
        if name.is_empty() {
            name = "object".into();
        } else if !name.starts_with(|c: char| c.is_ascii_alphabetic()) {
            name.insert(0, 'o');
        }
        name.truncate(NAME_LEN - 1);
        Self(name)
    }

    /// The name.
    pub fn as_str(&self) -> &str {
        &self.0
    }

    /// The name's wire bytes, NUL-padded.
    pub fn bytes(&self) -> [u8; NAME_LEN] {
        let mut out = [0u8; NAME_LEN];
        out[..self.0.len()].copy_from_slice(self.0.as_bytes());
        out
    }
}

impl std::fmt::Display for ObjectName {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
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
    fn pose_set_layout_is_the_version_2_contract() {
        assert_eq!(size_of::<ObjectPose>(), 144);
        assert_eq!((offset_of!(ObjectPose, name), offset_of!(ObjectPose, pose)), (0, 32));
        assert_eq!(size_of::<PoseSet>(), 8 + 8 * 144);
        assert_eq!(align_of::<PoseSet>(), 8);
        let offsets = [
            offset_of!(PoseSet, count),
            offset_of!(PoseSet, reserved),
            offset_of!(PoseSet, objects),
        ];
        assert_eq!(offsets, [0, 4, 8]);
    }

    #[test]
    fn pose_sets_keep_names_and_refuse_a_ninth_object() {
        let mut set = PoseSet::default();
        for i in 0..MAX_OBJECTS {
            let pose = PoseMsg {
                frame_id: i as u64,
                ..Default::default()
            };
            set.push(&ObjectName::new(&format!("card_{i}")).unwrap(), pose).unwrap();
        }
        assert_eq!(
            set.push(&ObjectName::new("extra").unwrap(), PoseMsg::default()),
            Err(SetFull)
        );
        assert_eq!(set.get("card_3").map(|p| p.frame_id), Some(3));
        assert_eq!(set.objects()[7].name(), "card_7");
        set.count = 99;
        assert_eq!(set.objects().len(), MAX_OBJECTS, "a corrupt count is clamped");
    }

    #[test]
    fn object_names_are_ros_name_components() {
        assert!(ObjectName::new("cup_2").is_ok());
        let long = "a".repeat(32);
        for (bad, why) in [
            ("", "start with"),
            ("2cup", "start with"),
            ("my-cup", "only ASCII"),
            ("cup/x", "only ASCII"),
            (long.as_str(), "longer than 31"),
        ] {
            let e = ObjectName::new(bad).unwrap_err();
            assert!(e.contains(why), "{bad:?}: {e}");
        }
        assert_eq!(ObjectName::from_stem("rocket.v2").as_str(), "rocket_v2");
        assert_eq!(ObjectName::from_stem("3d-box").as_str(), "o3d_box");
        assert_eq!(ObjectName::from_stem("").as_str(), "object");
        assert_eq!(ObjectName::from_stem(&"x".repeat(40)).as_str().len(), 31);
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

    fn hd(format: PixelFormat) -> FrameHeader {
        let stride = 2 * 1280 * format.bytes_per_pixel() as u32;
        FrameHeader {
            width: 1280,
            height: 720,
            pixel_format: format.code(),
            row_stride: stride,
            ..Default::default()
        }
    }

    #[test]
    fn frames_whose_header_matches_the_payload_pass() {
        for format in [PixelFormat::Rgb8, PixelFormat::Yuyv] {
            let h = hd(format);
            assert_eq!(validate_frame(&h, 720 * h.row_stride as usize), Ok(format));
            // Padded rows are fine when the payload holds them.
            let padded = FrameHeader {
                row_stride: h.row_stride + 64,
                ..h
            };
            assert_eq!(validate_frame(&padded, 720 * padded.row_stride as usize), Ok(format));
        }
    }

    #[test]
    fn each_disagreement_has_its_reason() {
        let h = hd(PixelFormat::Rgb8);
        let len = 720 * 7680;
        let cases = [
            (FrameHeader { pixel_format: 9, ..h }, len, "unknown pixel format code 9"),
            (FrameHeader { width: 0, ..h }, len, "empty image (0x720 per eye)"),
            (FrameHeader { height: 0, ..h }, 0, "empty image (1280x0 per eye)"),
            (
                FrameHeader { row_stride: 7679, ..h },
                len,
                "row stride 7679 is shorter than a side-by-side row of 7680 bytes",
            ),
            // A YUYV header on an RGB8-sized payload.
            (
                FrameHeader {
                    pixel_format: pixel_format::YUYV,
                    row_stride: 5120,
                    ..h
                },
                len,
                "payload of 5529600 bytes, but the header says 3686400 (720 rows of 5120 bytes)",
            ),
            (
                h,
                len - 1,
                "payload of 5529599 bytes, but the header says 5529600 (720 rows of 7680 bytes)",
            ),
            (
                FrameHeader {
                    width: u32::MAX,
                    row_stride: u32::MAX,
                    ..h
                },
                len,
                "row stride 4294967295 is shorter than a side-by-side row of 25769803770 bytes",
            ),
        ];
        for (header, len, reason) in cases {
            assert_eq!(validate_frame(&header, len).unwrap_err().to_string(), reason);
        }
    }

    #[test]
    fn sanitize_normalises_or_declares_lost() {
        let good = PoseMsg {
            frame_id: 7,
            position_mm: [1.0, 2.0, 600.0],
            orientation_wxyz: [-2.0, 0.0, 0.0, 0.0],
            size_mm: [100.0, 80.0],
            fitness: 1.5,
            status: Status::Tracking as u32,
            ..Default::default()
        };
        let mut p = good;
        p.sanitize();
        assert_eq!(p.orientation_wxyz, [1.0, 0.0, 0.0, 0.0]);
        assert_eq!((p.status, p.position_mm), (Status::Tracking as u32, good.position_mm));
        assert!(p.is_sound());
        let broken = [
            PoseMsg {
                position_mm: [f64::NAN, 0.0, 0.0],
                ..good
            },
            PoseMsg {
                size_mm: [f64::INFINITY, 1.0],
                ..good
            },
            PoseMsg {
                orientation_wxyz: [0.0; 4],
                ..good
            },
            PoseMsg {
                orientation_wxyz: [f64::NAN, 1.0, 0.0, 0.0],
                ..good
            },
            PoseMsg {
                fitness: f64::NAN,
                ..good
            },
            PoseMsg { status: 9, ..good },
        ];
        for b in broken {
            assert!(!b.is_sound(), "{b:?}");
            let mut p = b;
            p.sanitize();
            assert!(p.is_sound(), "{p:?}");
            assert_eq!(p.status, Status::Lost as u32, "{b:?}");
            assert_eq!((p.frame_id, p.position_mm, p.fitness), (7, [0.0; 3], 0.0));
        }
    }

    #[test]
    fn monotonic_clock_advances() {
        let a = monotonic_ns();
        std::thread::sleep(std::time::Duration::from_millis(2));
        let b = monotonic_ns();
        assert!(b >= a + 1_000_000, "{a} {b}");
    }
}
