//! A scripted camera for tests: each attempt to open it follows a script (it opens and
//! delivers a list of [`Step`]s, is missing, or offers VGA only), so the streaming and
//! reconnect logic of [`super::stream`] runs without hardware.

use std::collections::VecDeque;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use super::device::{CameraInfo, Device, DeviceError, Filled, Opener, TIMESTAMP_MONOTONIC};
use super::discovery::{DiscoveryError, ZED_2I_PRODUCT};
use super::{Mode, MODES};
use crate::camera::calibration::Resolution;

/// What the camera does on one call to [`Device::next`].
#[derive(Debug, Clone)]
pub enum Step {
    /// A filled buffer.
    Frame {
        /// The buffer's bytes.
        bytes: Arc<[u8]>,
        /// The driver's timestamp, ns.
        timestamp_ns: u64,
        /// V4L2 buffer flags (timestamp source).
        flags: u32,
    },
    /// A buffer holding only this many bytes.
    Short(usize),
    /// No buffer within the wait, after this long.
    Silence(Duration),
    /// The camera is unplugged (ENODEV); every later call fails too.
    Unplug,
}

impl Step {
    /// A complete frame stamped `timestamp_ns` on CLOCK_MONOTONIC.
    pub fn frame(bytes: Arc<[u8]>, timestamp_ns: u64) -> Self {
        Step::Frame {
            bytes,
            timestamp_ns,
            flags: TIMESTAMP_MONOTONIC,
        }
    }
}

/// What one attempt to open the camera finds.
#[derive(Debug, Clone)]
pub enum Attempt {
    /// The camera opens and plays these steps, then behaves as unplugged.
    Opens(Vec<Step>),
    /// No camera.
    Missing,
    /// The camera is on a USB 2 link and offers VGA modes only.
    Usb2,
}

/// The node the fake camera claims.
pub const FAKE_NODE: &str = "/dev/video0";

/// Opens [`ScriptedDevice`]s attempt by attempt; past the script the camera is missing.
#[derive(Debug, Default)]
pub struct ScriptedOpener {
    attempts: VecDeque<Attempt>,
    /// Attempts made so far, and the modes asked for.
    pub requested: Vec<Mode>,
}

impl ScriptedOpener {
    /// An opener whose successive `open` calls play `attempts`.
    pub fn new(attempts: impl IntoIterator<Item = Attempt>) -> Self {
        Self {
            attempts: attempts.into_iter().collect(),
            requested: Vec::new(),
        }
    }
}

impl Opener for ScriptedOpener {
    fn open(&mut self, mode: Mode) -> Result<(Box<dyn Device>, CameraInfo), DeviceError> {
        self.requested.push(mode);
        let node = PathBuf::from(FAKE_NODE);
        match self.attempts.pop_front().unwrap_or(Attempt::Missing) {
            Attempt::Missing => Err(DiscoveryError::NoCamera {
                dir: "/sys/class/video4linux".into(),
            }
            .into()),
            Attempt::Usb2 if mode.resolution != Resolution::VGA => Err(DeviceError::ModeNotOffered {
                node,
                mode,
                offered: MODES
                    .iter()
                    .copied()
                    .filter(|m| m.resolution == Resolution::VGA)
                    .collect(),
                usb_speed_mbps: Some(480),
            }),
            Attempt::Usb2 => Ok((Box::new(ScriptedDevice::new(Vec::new())), info(Some(480)))),
            Attempt::Opens(steps) => Ok((Box::new(ScriptedDevice::new(steps)), info(Some(5000)))),
        }
    }
}

fn info(usb_speed_mbps: Option<u32>) -> CameraInfo {
    CameraInfo {
        node: FAKE_NODE.into(),
        product: Some(ZED_2I_PRODUCT),
        serial: Some("12345".into()),
        usb_speed_mbps,
    }
}

/// A streaming fake camera playing its steps.
#[derive(Debug)]
pub struct ScriptedDevice {
    steps: VecDeque<Step>,
    buffer: Arc<[u8]>,
}

impl ScriptedDevice {
    /// A device whose successive `next` calls play `steps`.
    pub fn new(steps: Vec<Step>) -> Self {
        Self {
            steps: steps.into(),
            buffer: Arc::from(Vec::new()),
        }
    }
}

impl Device for ScriptedDevice {
    fn next(&mut self, _timeout: Duration) -> Result<Option<Filled<'_>>, DeviceError> {
        let (timestamp_ns, flags) = match self.steps.pop_front() {
            Some(Step::Frame {
                bytes,
                timestamp_ns,
                flags,
            }) => {
                self.buffer = bytes;
                (timestamp_ns, flags)
            }
            Some(Step::Short(len)) => {
                self.buffer = Arc::from(vec![0u8; len]);
                (0, TIMESTAMP_MONOTONIC)
            }
            Some(Step::Silence(wait)) => {
                std::thread::sleep(wait);
                return Ok(None);
            }
            Some(Step::Unplug) | None => {
                self.steps.clear();
                self.steps.push_back(Step::Unplug);
                return Err(DeviceError::io(
                    std::path::Path::new(FAKE_NODE),
                    "VIDIOC_DQBUF",
                    std::io::Error::from_raw_os_error(libc::ENODEV),
                ));
            }
        };
        Ok(Some(Filled {
            bytes: &self.buffer,
            timestamp_ns,
            flags,
        }))
    }
}
