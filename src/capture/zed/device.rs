//! The device layer under the ZED source: opening the camera in a mode and taking its
//! filled buffers. `super::v4l2` implements it on the kernel, [`super::fake`] from a
//! script.

use std::path::PathBuf;
use std::time::Duration;

use super::discovery::DiscoveryError;
use super::{mode_list, Mode};

/// V4L2 buffer flags: where the timestamp comes from (`V4L2_BUF_FLAG_TIMESTAMP_*`).
pub const TIMESTAMP_MASK: u32 = 0xe000;
/// The timestamp is CLOCK_MONOTONIC.
pub const TIMESTAMP_MONOTONIC: u32 = 0x2000;
/// The driver marked the buffer's data as damaged (`V4L2_BUF_FLAG_ERROR`).
pub const BUFFER_ERROR: u32 = 0x0040;

/// A buffer the camera filled: valid until the next call to [`Device::next`].
#[derive(Debug, Clone, Copy)]
pub struct Filled<'a> {
    /// The bytes the driver wrote (`bytesused`).
    pub bytes: &'a [u8],
    /// The driver's timestamp, ns, in the clock the flags name.
    pub timestamp_ns: u64,
    /// `v4l2_buffer.flags`.
    pub flags: u32,
}

/// A streaming camera.
pub trait Device {
    /// Hands the previous buffer back to the driver and waits up to `timeout` for the
    /// next filled one; `Ok(None)` when none came.
    fn next(&mut self, timeout: Duration) -> Result<Option<Filled<'_>>, DeviceError>;
}

/// What was opened.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CameraInfo {
    /// `/dev/videoN`.
    pub node: PathBuf,
    /// USB product (vendor 0x2b03), when sysfs knows the node.
    pub product: Option<u16>,
    /// The camera's serial number, when sysfs has it (it names the calibration file).
    pub serial: Option<String>,
    /// USB link speed, Mb/s.
    pub usb_speed_mbps: Option<u32>,
}

/// Opens the camera, streaming.
pub trait Opener {
    /// Finds the camera, sets `mode` and starts streaming.
    fn open(&mut self, mode: Mode) -> Result<(Box<dyn Device>, CameraInfo), DeviceError>;
}

/// A camera that cannot be opened or stopped delivering.
#[derive(Debug, thiserror::Error)]
pub enum DeviceError {
    /// No camera or no calibration was found.
    #[error(transparent)]
    Discovery(#[from] DiscoveryError),
    /// The video node cannot be opened.
    #[error("cannot open {}: {error}", .node.display())]
    Open {
        /// `/dev/videoN`.
        node: PathBuf,
        /// The system's reason.
        error: std::io::Error,
    },
    /// The node cannot capture video with streaming I/O.
    #[error("{} is not a video capture device with streaming I/O", .node.display())]
    NotCapture {
        /// `/dev/videoN`.
        node: PathBuf,
    },
    /// The camera does not offer the requested mode (often: plugged into USB 2).
    #[error("{} does not offer {mode} in YUYV; it offers {}{}", .node.display(), mode_list(.offered), usb2_hint(.offered, *.usb_speed_mbps))]
    ModeNotOffered {
        /// `/dev/videoN`.
        node: PathBuf,
        /// The mode asked for.
        mode: Mode,
        /// The YUYV modes the camera offers.
        offered: Vec<Mode>,
        /// USB link speed, Mb/s, when known.
        usb_speed_mbps: Option<u32>,
    },
    /// The driver accepted the mode request but set another format.
    #[error("{}: the driver set {got} instead of {mode}", .node.display())]
    ModeRefused {
        /// `/dev/videoN`.
        node: PathBuf,
        /// The mode asked for.
        mode: Mode,
        /// The format the driver set instead, in words.
        got: String,
    },
    /// The camera disappeared (ENODEV).
    #[error("{} was unplugged", .node.display())]
    Unplugged {
        /// `/dev/videoN`.
        node: PathBuf,
    },
    /// Another device call failed.
    #[error("{}: {op} failed: {error}", .node.display())]
    Io {
        /// `/dev/videoN`.
        node: PathBuf,
        /// The ioctl or call that failed.
        op: &'static str,
        /// The system's reason.
        error: std::io::Error,
    },
}

impl DeviceError {
    /// An I/O error of `op` on `node`; ENODEV means the camera is gone.
    pub fn io(node: &std::path::Path, op: &'static str, error: std::io::Error) -> Self {
        if error.raw_os_error() == Some(libc::ENODEV) {
            DeviceError::Unplugged {
                node: node.to_path_buf(),
            }
        } else {
            DeviceError::Io {
                node: node.to_path_buf(),
                op,
                error,
            }
        }
    }
}

/// Why a camera offers only VGA: a USB 2 link (the ZED 2i needs USB 3 for more).
fn usb2_hint(offered: &[Mode], usb_speed_mbps: Option<u32>) -> String {
    let only_vga = !offered.is_empty()
        && offered
            .iter()
            .all(|m| m.resolution == crate::camera::calibration::Resolution::VGA);
    match usb_speed_mbps {
        Some(speed) if speed < 5000 => format!(
            " (the camera is on a USB 2 link, {speed} Mb/s, which carries VGA only: connect it to a USB 3 port with a USB 3 cable)"
        ),
        _ if only_vga => " (only VGA: the camera is probably on a USB 2 port or cable; connect it to USB 3)".into(),
        _ => String::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::calibration::Resolution;

    fn not_offered(offered: Vec<Mode>, usb_speed_mbps: Option<u32>) -> String {
        DeviceError::ModeNotOffered {
            node: "/dev/video0".into(),
            mode: Mode::new(Resolution::HD, 60),
            offered,
            usb_speed_mbps,
        }
        .to_string()
    }

    #[test]
    fn a_usb2_link_is_named_when_the_mode_is_missing() {
        let vga: Vec<Mode> = super::super::MODES
            .iter()
            .copied()
            .filter(|m| m.resolution == Resolution::VGA)
            .collect();
        assert_eq!(
            not_offered(vga.clone(), Some(480)),
            "/dev/video0 does not offer HD (2×1280×720) at 60 fps in YUYV; it offers VGA@15/30/60/100 \
             (the camera is on a USB 2 link, 480 Mb/s, which carries VGA only: connect it to a USB 3 port with a USB 3 cable)"
        );
        assert!(not_offered(vga, None)
            .ends_with("(only VGA: the camera is probably on a USB 2 port or cable; connect it to USB 3)"));
        let e = not_offered(vec![Mode::new(Resolution::HD, 30)], Some(5000));
        assert!(e.ends_with("it offers HD@30"), "{e}");
    }

    #[test]
    fn enodev_means_unplugged() {
        let node = std::path::Path::new("/dev/video0");
        let e = DeviceError::io(node, "VIDIOC_DQBUF", std::io::Error::from_raw_os_error(libc::ENODEV));
        assert_eq!(e.to_string(), "/dev/video0 was unplugged");
        let e = DeviceError::io(node, "VIDIOC_DQBUF", std::io::Error::from_raw_os_error(libc::EIO));
        assert!(e.to_string().starts_with("/dev/video0: VIDIOC_DQBUF failed: "), "{e}");
    }
}
