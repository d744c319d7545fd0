//! The ZED as a [`FrameSource`]: complete buffers only, timestamps checked, and a camera
//! that goes away (unplugged, USB error, stalled) is closed and opened again with
//! back-off while nothing is published.

use std::time::{Duration, Instant};

use super::device::{CameraInfo, Device, DeviceError, Opener, BUFFER_ERROR, TIMESTAMP_MASK, TIMESTAMP_MONOTONIC};
use super::discovery::product_name;
use super::Mode;
use crate::capture::{FrameBuf, FrameInfo, FrameSource, Geometry, SourceError, Written};
use crate::transport::messages::monotonic_ns;

/// How long one [`FrameSource::write_frame`] waits for a buffer (bounds how late a stop request
/// is noticed).
const WAIT: Duration = Duration::from_millis(100);

/// Reopening a lost camera: the first wait, doubled after each failed attempt up to
/// `max`; a camera silent for `stall` counts as lost.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Backoff {
    /// Wait before the first reopen.
    pub first: Duration,
    /// Longest wait between reopens.
    pub max: Duration,
    /// Silence after which an open camera counts as lost.
    pub stall: Duration,
}

impl Default for Backoff {
    fn default() -> Self {
        Self {
            first: Duration::from_millis(100),
            max: Duration::from_secs(2),
            stall: Duration::from_secs(2),
        }
    }
}

/// What the source has seen.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct ZedStats {
    /// Frames delivered.
    pub frames: u64,
    /// Short or damaged buffers, given back to the driver unpublished.
    pub short: u64,
    /// Times the camera was lost.
    pub lost: u64,
    /// Times it was opened again.
    pub reconnects: u64,
    /// Failed attempts to open it again.
    pub failed_opens: u64,
    /// Frames stamped with the receive time (the driver's clock was not CLOCK_MONOTONIC).
    pub receive_stamped: u64,
}

/// A ZED camera, through any [`Opener`].
pub struct ZedSource<O: Opener> {
    opener: O,
    mode: Mode,
    backoff: Backoff,
    info: CameraInfo,
    device: Option<Box<dyn Device>>,
    /// Last frame (or open) time, for stall detection.
    last_frame: Instant,
    /// While lost: the next attempt and the wait after it fails.
    retry_at: Instant,
    delay: Duration,
    /// Frames, short buffers, reconnects and timestamp fallbacks so far.
    pub stats: ZedStats,
}

impl<O: Opener> ZedSource<O> {
    /// Opens the camera in `mode`; failing here is final (nothing to resume).
    pub fn open(mut opener: O, mode: Mode, backoff: Backoff) -> Result<Self, DeviceError> {
        let (device, info) = opener.open(mode)?;
        match info.product {
            Some(super::discovery::ZED_2I_PRODUCT) | None => {}
            Some(p) => tracing::warn!(
                "capture: {} is a {}, not a ZED 2i: its modes and calibration may differ",
                info.node.display(),
                product_name(p)
            ),
        }
        if let Some(speed) = info.usb_speed_mbps.filter(|&s| s < 5000) {
            tracing::warn!("capture: the camera is on a USB 2 link ({speed} Mb/s): only VGA modes will work");
        }
        let now = Instant::now();
        Ok(Self {
            opener,
            mode,
            backoff,
            info,
            device: Some(device),
            last_frame: now,
            retry_at: now,
            delay: backoff.first,
            stats: ZedStats::default(),
        })
    }

    /// The camera as last opened (a reconnect replaces it).
    pub fn info(&self) -> &CameraInfo {
        &self.info
    }

    /// The opener (tests inspect what was asked of it).
    pub fn opener(&self) -> &O {
        &self.opener
    }

    /// True while the camera is open.
    pub fn is_streaming(&self) -> bool {
        self.device.is_some()
    }

    /// Closes a camera that failed and schedules the first attempt to reopen it.
    fn lose(&mut self, why: &dyn std::fmt::Display) {
        tracing::warn!("capture: camera lost: {why}; opening it again");
        self.device = None;
        self.stats.lost += 1;
        self.delay = self.backoff.first;
        self.retry_at = Instant::now() + self.delay;
    }

    fn reopen(&mut self) {
        match self.opener.open(self.mode) {
            Ok((device, info)) => {
                tracing::info!(
                    "capture: camera back on {} after {} failed attempt(s)",
                    info.node.display(),
                    self.stats.failed_opens
                );
                self.device = Some(device);
                self.info = info;
                self.last_frame = Instant::now();
                self.stats.reconnects += 1;
            }
            Err(e) => {
                self.stats.failed_opens += 1;
                self.delay = (self.delay * 2).min(self.backoff.max);
                tracing::warn!("capture: camera not back yet ({e}); next attempt in {:?}", self.delay);
                self.retry_at = Instant::now() + self.delay;
            }
        }
    }
}

impl<O: Opener> FrameSource for ZedSource<O> {
    fn geometry(&self) -> Geometry {
        self.mode.geometry()
    }

    fn describe(&self) -> String {
        let i = &self.info;
        let name = i.product.map_or_else(|| "ZED".to_string(), product_name);
        let serial = i
            .serial
            .as_deref()
            .map_or_else(String::new, |s| format!(", serial {s}"));
        let speed = i.usb_speed_mbps.map_or_else(String::new, |s| format!(", USB {s} Mb/s"));
        format!("{name} on {}{serial}{speed}: {} YUYV", i.node.display(), self.mode)
    }

    fn next_due(&mut self) -> Option<Instant> {
        Some(match self.device {
            Some(_) => Instant::now(),
            None => self.retry_at,
        })
    }

    fn write_frame<'a>(&mut self, buf: FrameBuf<'a>) -> Result<Option<(FrameInfo, Written<'a>)>, SourceError> {
        let Some(device) = self.device.as_mut() else {
            if Instant::now() >= self.retry_at {
                self.reopen();
            }
            return Ok(None);
        };
        let filled = match device.next(WAIT) {
            Ok(Some(f)) => f,
            Ok(None) => {
                let silent = self.last_frame.elapsed();
                if silent >= self.backoff.stall {
                    self.lose(&format_args!("no frame for {:.1} s", silent.as_secs_f64()));
                }
                return Ok(None);
            }
            Err(e) => {
                self.lose(&e);
                return Ok(None);
            }
        };
        self.last_frame = Instant::now();
        if filled.bytes.len() < buf.len() || filled.flags & BUFFER_ERROR != 0 {
            self.stats.short += 1;
            if self.stats.short.is_power_of_two() {
                tracing::warn!(
                    "capture: incomplete buffer ({} of {} bytes{}) dropped; {} so far",
                    filled.bytes.len(),
                    buf.len(),
                    if filled.flags & BUFFER_ERROR != 0 {
                        ", error flag"
                    } else {
                        ""
                    },
                    self.stats.short
                );
            }
            return Ok(None);
        }
        let len = buf.len();
        let frame = buf.copy_from(&filled.bytes[..len])?;
        let monotonic = filled.flags & TIMESTAMP_MASK == TIMESTAMP_MONOTONIC && filled.timestamp_ns > 0;
        let capture_time_ns = if monotonic {
            filled.timestamp_ns
        } else {
            if self.stats.receive_stamped == 0 {
                tracing::warn!(
                    "capture: the driver's buffer timestamps are not CLOCK_MONOTONIC (flags 0x{:x}); frames carry their receive time",
                    filled.flags
                );
            }
            self.stats.receive_stamped += 1;
            monotonic_ns()
        };
        self.stats.frames += 1;
        let info = FrameInfo::single(capture_time_ns, None);
        Ok(Some((info, frame)))
    }

    fn summary(&self) -> Option<String> {
        let s = &self.stats;
        Some(format!(
            "{} frames, {} incomplete buffers dropped, camera lost {} time(s), reopened {} time(s)",
            s.frames, s.short, s.lost, s.reconnects
        ))
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::camera::calibration::Resolution;
    use crate::capture::zed::fake::{Attempt, ScriptedOpener, Step};

    const VGA: Mode = Mode::new(Resolution::VGA, 100);

    fn backoff() -> Backoff {
        Backoff {
            first: Duration::from_millis(1),
            max: Duration::from_millis(4),
            stall: Duration::from_secs(5),
        }
    }

    /// A VGA frame whose bytes are all `value`.
    fn frame(value: u8, timestamp_ns: u64) -> Step {
        Step::frame(Arc::from(vec![value; VGA.geometry().frame_len()]), timestamp_ns)
    }

    /// Runs the source as the capture process does (wait until due, fill) until `n`
    /// frames came or `max_calls` fills were made: each frame's first byte and time.
    fn drive(source: &mut ZedSource<ScriptedOpener>, n: usize, max_calls: usize) -> Vec<(u8, u64)> {
        let mut buf = vec![0u8; source.geometry().frame_len()];
        let mut out = Vec::new();
        for _ in 0..max_calls {
            let Some(due) = source.next_due() else { break };
            std::thread::sleep(due.saturating_duration_since(Instant::now()));
            buf.fill(0xee);
            if let Some(info) = source.fill(&mut buf).unwrap() {
                assert!(buf.iter().all(|&b| b == buf[0]), "a frame mixed two buffers");
                out.push((buf[0], info.capture_time_ns));
            }
            if out.len() == n {
                break;
            }
        }
        out
    }

    #[test]
    fn frames_flow_short_buffers_are_dropped_and_an_unplugged_camera_comes_back() {
        let opener = ScriptedOpener::new([
            Attempt::Opens(vec![frame(1, 1_000), Step::Short(1000), frame(2, 2_000), Step::Unplug]),
            Attempt::Missing,
            Attempt::Missing,
            Attempt::Opens(vec![frame(3, 3_000), Step::Short(0), frame(4, 4_000)]),
        ]);
        let mut source = ZedSource::open(opener, VGA, backoff()).unwrap();
        assert!(source
            .describe()
            .contains("ZED 2i on /dev/video0, serial 12345, USB 5000 Mb/s"));
        let start = Instant::now();
        let frames = drive(&mut source, 4, 100);
        // Nothing stale or partial is delivered: exactly the complete frames, in order,
        // with the driver's timestamps.
        assert_eq!(frames, [(1, 1_000), (2, 2_000), (3, 3_000), (4, 4_000)]);
        assert_eq!(
            source.stats,
            ZedStats {
                frames: 4,
                short: 2,
                lost: 1,
                reconnects: 1,
                failed_opens: 2,
                receive_stamped: 0,
            }
        );
        // Four opens in all, each asking for the same mode, after waits of 1, 2 and 4 ms.
        assert_eq!(source.opener().requested, [VGA; 4]);
        assert!(start.elapsed() >= Duration::from_millis(7), "{:?}", start.elapsed());
        assert_eq!(
            source.summary().unwrap(),
            "4 frames, 2 incomplete buffers dropped, camera lost 1 time(s), reopened 1 time(s)"
        );
        // After the script the camera is gone for good: nothing more is delivered.
        assert!(drive(&mut source, 1, 20).is_empty());
        assert!(!source.is_streaming());
        assert_eq!(source.stats.lost, 2);
    }

    #[test]
    fn the_back_off_doubles_up_to_its_limit() {
        let opener = ScriptedOpener::new(
            std::iter::once(Attempt::Opens(vec![Step::Unplug]))
                .chain(std::iter::repeat_n(Attempt::Missing, 5))
                .chain(std::iter::once(Attempt::Opens(vec![frame(7, 7)]))),
        );
        let mut source = ZedSource::open(opener, VGA, backoff()).unwrap();
        let mut waits = Vec::new();
        let mut buf = vec![0u8; VGA.geometry().frame_len()];
        for _ in 0..30 {
            let due = source.next_due().unwrap();
            if !source.is_streaming() {
                waits.push(due.saturating_duration_since(Instant::now()).as_secs_f64() * 1e3);
            }
            std::thread::sleep(due.saturating_duration_since(Instant::now()));
            if source.fill(&mut buf).unwrap().is_some() {
                break;
            }
        }
        assert_eq!((buf[0], source.stats.failed_opens, source.stats.reconnects), (7, 5, 1));
        // Waits before attempts 1..6: 1, 2, 4, 4, 4, 4 ms (read just before each sleep).
        let want = [1.0, 2.0, 4.0, 4.0, 4.0, 4.0];
        assert_eq!(waits.len(), want.len(), "{waits:?}");
        for (w, x) in waits.iter().zip(want) {
            assert!(*w <= x && *w > x - 0.9, "{waits:?}");
        }
    }

    #[test]
    fn a_silent_camera_is_reopened_and_odd_clocks_use_the_receive_time() {
        let silence = Step::Silence(Duration::from_millis(4));
        let opener = ScriptedOpener::new([
            Attempt::Opens(vec![silence.clone(), silence.clone(), silence.clone(), silence]),
            Attempt::Opens(vec![Step::Frame {
                bytes: Arc::from(vec![5u8; VGA.geometry().frame_len()]),
                timestamp_ns: 42,
                flags: 0x4000, // V4L2_BUF_FLAG_TIMESTAMP_COPY: not the capture clock
            }]),
        ]);
        let backoff = Backoff {
            stall: Duration::from_millis(10),
            ..backoff()
        };
        let mut source = ZedSource::open(opener, VGA, backoff).unwrap();
        let before = monotonic_ns();
        let frames = drive(&mut source, 1, 20);
        let after = monotonic_ns();
        assert_eq!(frames.len(), 1);
        assert_eq!(frames[0].0, 5);
        assert!(
            (before..=after).contains(&frames[0].1),
            "{} not in {before}..{after}",
            frames[0].1
        );
        assert_eq!(
            (source.stats.lost, source.stats.reconnects, source.stats.receive_stamped),
            (1, 1, 1)
        );
    }

    #[test]
    fn a_missing_camera_or_a_usb2_link_fails_at_start() {
        let e = ZedSource::open(ScriptedOpener::new([]), VGA, backoff())
            .err()
            .unwrap()
            .to_string();
        assert!(e.starts_with("no ZED camera found"), "{e}");
        let hd = Mode::new(Resolution::HD, 60);
        let e = ZedSource::open(ScriptedOpener::new([Attempt::Usb2]), hd, backoff())
            .err()
            .unwrap()
            .to_string();
        assert!(
            e.contains("offers VGA@15/30/60/100") && e.contains("USB 2 link, 480 Mb/s"),
            "{e}"
        );
        // VGA works over USB 2.
        let source = ZedSource::open(ScriptedOpener::new([Attempt::Usb2]), VGA, backoff()).unwrap();
        assert_eq!(source.info().usb_speed_mbps, Some(480));
    }
}
