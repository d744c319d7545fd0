//! The ROS 2 messages the bridge publishes, serialised with [`CdrWriter`]:
//! `geometry_msgs/msg/PoseStamped` (the pose, in metres) and
//! `diagnostic_msgs/msg/DiagnosticStatus` (tracking status, fitness, size).

use super::cdr::CdrWriter;
use crate::transport::messages::{PoseMsg, Status};

/// A ROS 2 message type as rmw_zenoh names it on the wire.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RosType {
    /// The ROS name, e.g. `geometry_msgs/msg/PoseStamped`.
    pub name: &'static str,
    /// The DDS type name in key expressions and liveliness tokens.
    pub dds_name: &'static str,
    /// The type description hash (REP 2016 `RIHS01`) of Jazzy and later, as rosbags
    /// 0.11.9 computes it for Jazzy and Kilted.
    pub hash: &'static str,
}

/// `geometry_msgs/msg/PoseStamped`.
pub const POSE_STAMPED: RosType = RosType {
    name: "geometry_msgs/msg/PoseStamped",
    dds_name: "geometry_msgs::msg::dds_::PoseStamped_",
    hash: "RIHS01_10f3786d7d40fd2b54367835614bff85d4ad3b5dab62bf8bca0cc232d73b4cd8",
};

/// `diagnostic_msgs/msg/DiagnosticStatus`.
pub const DIAGNOSTIC_STATUS: RosType = RosType {
    name: "diagnostic_msgs/msg/DiagnosticStatus",
    dds_name: "diagnostic_msgs::msg::dds_::DiagnosticStatus_",
    hash: "RIHS01_b0e3e692ea2d54a8af2f4ef1930e81556a2db55216b771f8a7d2724ed47bf0e4",
};

/// `DiagnosticStatus.hardware_id` of every status message.
pub const HARDWARE_ID: &str = "photopose";

/// A `builtin_interfaces/msg/Time`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Stamp {
    /// Whole seconds (negative before 1970).
    pub sec: i32,
    /// Nanoseconds past `sec`, below 10⁹.
    pub nanosec: u32,
}

impl Stamp {
    /// The time `ns` nanoseconds after the epoch (seconds saturate past 2038).
    pub fn from_ns(ns: i64) -> Self {
        let sec = ns.div_euclid(1_000_000_000);
        Stamp {
            sec: sec.clamp(i32::MIN.into(), i32::MAX.into()) as i32,
            nanosec: ns.rem_euclid(1_000_000_000) as u32,
        }
    }
}

/// Writes a `PoseStamped` of `pose` into `out`: position in metres (`mm / 1000`), the
/// quaternion in ROS order x, y, z, w.
pub fn pose_stamped(out: &mut Vec<u8>, stamp: Stamp, frame_id: &str, pose: &PoseMsg) {
    let [px, py, pz] = pose.position_mm.map(|v| v / 1000.0);
    let [w, x, y, z] = pose.orientation_wxyz;
    CdrWriter::new(out)
        .i32(stamp.sec)
        .u32(stamp.nanosec)
        .string(frame_id)
        .f64(px)
        .f64(py)
        .f64(pz)
        .f64(x)
        .f64(y)
        .f64(z)
        .f64(w);
}

/// `DiagnosticStatus.level` of a pose: OK when tracking, WARN when searching, ERROR
/// when lost or of an unknown status.
pub fn level(pose: &PoseMsg) -> u8 {
    match pose.status() {
        Ok(Status::Tracking) => 0,
        Ok(Status::Searching) => 1,
        Ok(Status::Lost) | Err(_) => 2,
    }
}

/// Writes the `DiagnosticStatus` of `object`'s pose into `out`: the level, the object as
/// name, the status name as message, and the values fitness, generations, frame_id,
/// size_x_m and size_y_m (floats in Rust's shortest round-trip form).
pub fn diagnostic_status(out: &mut Vec<u8>, object: &str, pose: &PoseMsg) {
    let message = pose.status().map_or("unknown", Status::name);
    let values: [(&str, String); 5] = [
        ("fitness", pose.fitness.to_string()),
        ("generations", pose.generations.to_string()),
        ("frame_id", pose.frame_id.to_string()),
        ("size_x_m", (pose.size_mm[0] / 1000.0).to_string()),
        ("size_y_m", (pose.size_mm[1] / 1000.0).to_string()),
    ];
    let mut w = CdrWriter::new(out);
    w.u8(level(pose)).string(object).string(message).string(HARDWARE_ID);
    w.sequence_len(values.len());
    for (key, value) in &values {
        w.string(key).string(value);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose() -> PoseMsg {
        PoseMsg {
            frame_id: 42,
            position_mm: [100.0, -20.5, 650.0],
            orientation_wxyz: [0.5, 0.5, -0.5, 0.5],
            size_mm: [180.0, 22.5],
            fitness: 1.25,
            generations: 40,
            status: 1,
            ..PoseMsg::default()
        }
    }

    fn f64_at(buf: &[u8], at: usize) -> f64 {
        f64::from_le_bytes(buf[at..at + 8].try_into().unwrap())
    }

    #[test]
    fn pose_stamped_has_the_hand_computed_offsets() {
        let mut buf = Vec::new();
        let stamp = Stamp::from_ns(1_700_000_000_123_456_789);
        pose_stamped(&mut buf, stamp, "hand", &pose());
        // Header 4; sec 4..8, nanosec 8..12, frame_id length 12..16, "hand\0" 16..21,
        // padding to body offset 24 (byte 28); 7 doubles.
        assert_eq!(buf.len(), 4 + 24 + 7 * 8);
        assert_eq!(buf[..4], [0, 1, 0, 0]);
        assert_eq!(buf[4..8], 1_700_000_000i32.to_le_bytes());
        assert_eq!(buf[8..12], 123_456_789u32.to_le_bytes());
        assert_eq!(buf[12..16], 5u32.to_le_bytes());
        assert_eq!(&buf[16..21], b"hand\0");
        assert_eq!(buf[21..28], [0; 7]);
        let doubles: Vec<f64> = (0..7).map(|i| f64_at(&buf, 28 + 8 * i)).collect();
        assert_eq!(doubles, [0.1, -0.0205, 0.65, 0.5, -0.5, 0.5, 0.5]);
    }

    #[test]
    fn stamps_split_negative_times_the_ros_way() {
        assert_eq!(
            Stamp::from_ns(-1),
            Stamp {
                sec: -1,
                nanosec: 999_999_999
            }
        );
        assert_eq!(
            Stamp::from_ns(2_500_000_000),
            Stamp {
                sec: 2,
                nanosec: 500_000_000
            }
        );
    }

    #[test]
    fn diagnostic_status_layout() {
        let mut buf = Vec::new();
        diagnostic_status(&mut buf, "cup", &pose());
        // level 4; pad to 8; name len 8..12 "cup\0" 12..16; message len 16..20
        // "searching\0" 20..30; pad to 32; hardware_id len 32..36 "photopose\0" 36..46;
        // pad to 48; values count 48..52.
        assert_eq!(buf[4], 1);
        assert_eq!(buf[5..8], [0; 3]);
        assert_eq!(buf[8..12], 4u32.to_le_bytes());
        assert_eq!(&buf[12..16], b"cup\0");
        assert_eq!(buf[16..20], 10u32.to_le_bytes());
        assert_eq!(&buf[20..30], b"searching\0");
        assert_eq!(buf[32..36], 10u32.to_le_bytes());
        assert_eq!(&buf[36..46], b"photopose\0");
        assert_eq!(buf[48..52], 5u32.to_le_bytes());
        assert_eq!(buf[52..56], 8u32.to_le_bytes());
        assert_eq!(&buf[56..64], b"fitness\0");
        assert_eq!(buf[64..68], 5u32.to_le_bytes());
        assert_eq!(&buf[68..73], b"1.25\0");
        let text = String::from_utf8_lossy(&buf);
        for s in [
            "generations\0",
            "40\0",
            "frame_id\0",
            "42\0",
            "size_x_m\0",
            "0.18\0",
            "size_y_m\0",
            "0.0225\0",
        ] {
            assert!(text.contains(s), "{s:?} missing");
        }
    }

    #[test]
    fn levels_follow_the_status() {
        let with = |status| level(&PoseMsg { status, ..pose() });
        assert_eq!([with(0), with(1), with(2), with(9)], [0, 1, 2, 2]);
    }
}
