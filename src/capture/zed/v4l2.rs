//! The real camera: a UVC device through V4L2 (the `v4l` crate for the device, its
//! formats and frame intervals; the memory-mapped buffer queue is driven here with raw
//! ioctls, so a timeout or an unplugged camera never re-queues a buffer twice or panics
//! when the stream is torn down).
//!
//! Why not the `v4l` crate's `MmapStream` (v4l 0.14): its `next()` first re-queues the
//! buffer it handed out last, then waits for the next one; when that wait times out or
//! fails, the following `next()` queues the same buffer a second time, which the driver
//! refuses, and the stream is stuck. Dropping it panics on any error but `ENODEV` while
//! stopping the stream or releasing the buffers. Here a buffer is queued again only
//! after it has been dequeued and read, each wait is one `poll` with the caller's
//! timeout, and tear-down errors are ignored.

use std::path::{Path, PathBuf};
use std::time::Duration;

use v4l::buffer::Type;
use v4l::frameinterval::FrameIntervalEnum;
use v4l::framesize::FrameSizeEnum;
use v4l::v4l_sys::{v4l2_buffer, v4l2_requestbuffers};
use v4l::video::capture::Parameters;
use v4l::video::Capture;
use v4l::{v4l2, Format, FourCC, Memory};

use super::device::{CameraInfo, Device, DeviceError, Filled, Opener};
use super::discovery::{Camera, Sysfs};
use super::{Mode, MODES};

/// Buffers in the driver's queue.
const BUFFERS: u32 = 4;

/// Opens the ZED found in sysfs, or the node `--device` named.
#[derive(Debug, Clone, Default)]
pub struct V4l2Opener {
    /// The node `--device` named; otherwise the ZED found in sysfs.
    pub device: Option<PathBuf>,
    /// Where cameras are looked for.
    pub sysfs: Sysfs,
}

impl Opener for V4l2Opener {
    fn open(&mut self, mode: Mode) -> Result<(Box<dyn Device>, CameraInfo), DeviceError> {
        let camera = match &self.device {
            Some(node) => self.sysfs.describe(node).map_or_else(
                || Camera {
                    node: node.clone(),
                    id: super::discovery::UsbId { vendor: 0, product: 0 },
                    serial: None,
                    usb_speed_mbps: None,
                },
                |c| Camera {
                    node: node.clone(),
                    ..c
                },
            ),
            None => self.sysfs.find_zed()?,
        };
        let node = camera.node.clone();
        let dev = v4l::Device::with_path(&node).map_err(|error| DeviceError::Open {
            node: node.clone(),
            error,
        })?;
        let caps = dev
            .query_caps()
            .map_err(|e| DeviceError::io(&node, "VIDIOC_QUERYCAP", e))?;
        let wanted = v4l::capability::Flags::VIDEO_CAPTURE | v4l::capability::Flags::STREAMING;
        if !caps.capabilities.contains(wanted) {
            return Err(DeviceError::NotCapture { node });
        }
        let yuyv = FourCC::new(b"YUYV");
        let offered = offered_modes(&dev, yuyv).map_err(|e| DeviceError::io(&node, "VIDIOC_ENUM_FRAMESIZES", e))?;
        if !offered.contains(&mode) {
            return Err(DeviceError::ModeNotOffered {
                node,
                mode,
                offered,
                usb_speed_mbps: camera.usb_speed_mbps,
            });
        }
        let (w, h) = mode.resolution.size();
        let set = dev
            .set_format(&Format::new(2 * w, h, yuyv))
            .map_err(|e| DeviceError::io(&node, "VIDIOC_S_FMT", e))?;
        let geometry = mode.geometry();
        if (set.width, set.height, set.fourcc) != (2 * w, h, yuyv) || set.stride as usize != geometry.row_stride() {
            return Err(DeviceError::ModeRefused {
                node,
                mode,
                got: format!("{}x{} {} (stride {})", set.width, set.height, set.fourcc, set.stride),
            });
        }
        let params = dev
            .set_params(&Parameters::with_fps(mode.fps))
            .map_err(|e| DeviceError::io(&node, "VIDIOC_S_PARM", e))?;
        let i = params.interval;
        if i.numerator == 0 || i.denominator / i.numerator != mode.fps {
            return Err(DeviceError::ModeRefused {
                node,
                mode,
                got: format!("a frame interval of {}/{} s", i.numerator, i.denominator),
            });
        }
        let stream = MmapStream::start(&dev, &node)?;
        let info = CameraInfo {
            node,
            product: (camera.id.vendor == super::discovery::ZED_VENDOR).then_some(camera.id.product),
            serial: camera.serial,
            usb_speed_mbps: camera.usb_speed_mbps,
        };
        Ok((Box::new(V4l2Device { _dev: dev, stream }), info))
    }
}

/// The table modes the device offers in `fourcc` (discrete sizes and intervals, as UVC
/// cameras list them).
fn offered_modes(dev: &v4l::Device, fourcc: FourCC) -> std::io::Result<Vec<Mode>> {
    let mut out = Vec::new();
    for size in dev.enum_framesizes(fourcc)? {
        let FrameSizeEnum::Discrete(d) = size.size else {
            continue;
        };
        for interval in dev.enum_frameintervals(fourcc, d.width, d.height)? {
            let FrameIntervalEnum::Discrete(f) = interval.interval else {
                continue;
            };
            if f.numerator == 0 {
                continue;
            }
            let fps = (f.denominator as f64 / f.numerator as f64).round() as u32;
            out.extend(
                MODES.iter().filter(|m| {
                    m.fps == fps && (2 * m.resolution.size().0, m.resolution.size().1) == (d.width, d.height)
                }),
            );
        }
    }
    out.sort_by_key(|m| MODES.iter().position(|x| x == m));
    out.dedup();
    Ok(out)
}

struct V4l2Device {
    stream: MmapStream,
    /// Keeps the device (its file descriptor) open while streaming.
    _dev: v4l::Device,
}

impl Device for V4l2Device {
    fn next(&mut self, timeout: Duration) -> Result<Option<Filled<'_>>, DeviceError> {
        self.stream.next(timeout)
    }
}

/// Memory-mapped buffers of a streaming capture device.
struct MmapStream {
    node: PathBuf,
    fd: std::os::raw::c_int,
    buffers: Vec<(*mut u8, usize)>,
    /// The buffer the caller holds, re-queued on the next call.
    held: Option<u32>,
}

fn buffer_desc() -> v4l2_buffer {
    v4l2_buffer {
        type_: Type::VideoCapture as u32,
        memory: Memory::Mmap as u32,
        // SAFETY: v4l2_buffer is plain C data; all zeroes is its documented initial state.
        ..unsafe { std::mem::zeroed() }
    }
}

impl MmapStream {
    /// Requests, maps and queues the buffers and starts streaming.
    fn start(dev: &v4l::Device, node: &Path) -> Result<Self, DeviceError> {
        let fd = dev.handle().fd();
        let mut stream = Self {
            node: node.to_path_buf(),
            fd,
            buffers: Vec::new(),
            held: None,
        };
        let mut req = v4l2_requestbuffers {
            count: BUFFERS,
            type_: Type::VideoCapture as u32,
            memory: Memory::Mmap as u32,
            // SAFETY: plain C data, zero-initialised as V4L2 expects.
            ..unsafe { std::mem::zeroed() }
        };
        stream.ioctl(v4l2::vidioc::VIDIOC_REQBUFS, &mut req, "VIDIOC_REQBUFS")?;
        for index in 0..req.count {
            let mut buf = v4l2_buffer { index, ..buffer_desc() };
            stream.ioctl(v4l2::vidioc::VIDIOC_QUERYBUF, &mut buf, "VIDIOC_QUERYBUF")?;
            let len = buf.length as usize;
            // SAFETY: for memory-mapped buffers the driver fills the union's `offset`.
            let offset = unsafe { buf.m.offset };
            // SAFETY: maps the buffer the driver just described (offset and length from
            // VIDIOC_QUERYBUF) on the open device; unmapped in Drop.
            let ptr = unsafe {
                v4l2::mmap(
                    std::ptr::null_mut(),
                    len,
                    libc::PROT_READ | libc::PROT_WRITE,
                    libc::MAP_SHARED,
                    fd,
                    offset as libc::off_t,
                )
            }
            .map_err(|e| DeviceError::io(node, "mmap", e))?;
            stream.buffers.push((ptr.cast(), len));
            stream.ioctl(v4l2::vidioc::VIDIOC_QBUF, &mut buf, "VIDIOC_QBUF")?;
        }
        let mut typ = Type::VideoCapture as u32;
        stream.ioctl(v4l2::vidioc::VIDIOC_STREAMON, &mut typ, "VIDIOC_STREAMON")?;
        Ok(stream)
    }

    fn ioctl<T>(&self, request: v4l2::vidioc::_IOC_TYPE, arg: &mut T, op: &'static str) -> Result<(), DeviceError> {
        // SAFETY: `arg` is the argument type of `request` (callers pair them as the V4L2
        // API defines) and lives across the call.
        unsafe { v4l2::ioctl(self.fd, request, (arg as *mut T).cast()) }.map_err(|e| DeviceError::io(&self.node, op, e))
    }

    fn next(&mut self, timeout: Duration) -> Result<Option<Filled<'_>>, DeviceError> {
        if let Some(index) = self.held.take() {
            let mut buf = v4l2_buffer { index, ..buffer_desc() };
            self.ioctl(v4l2::vidioc::VIDIOC_QBUF, &mut buf, "VIDIOC_QBUF")?;
        }
        let mut pfd = libc::pollfd {
            fd: self.fd,
            events: libc::POLLIN,
            revents: 0,
        };
        let ms = timeout.as_millis().min(i32::MAX as u128) as i32;
        // SAFETY: one valid pollfd.
        match unsafe { libc::poll(&mut pfd, 1, ms) } {
            0 => return Ok(None),
            -1 => {
                let e = std::io::Error::last_os_error();
                if e.kind() == std::io::ErrorKind::Interrupted {
                    return Ok(None);
                }
                return Err(DeviceError::io(&self.node, "poll", e));
            }
            _ if pfd.revents & (libc::POLLERR | libc::POLLHUP) != 0 && pfd.revents & libc::POLLIN == 0 => {
                return Err(DeviceError::io(
                    &self.node,
                    "poll",
                    std::io::Error::from_raw_os_error(libc::ENODEV),
                ));
            }
            _ => {}
        }
        let mut buf = buffer_desc();
        self.ioctl(v4l2::vidioc::VIDIOC_DQBUF, &mut buf, "VIDIOC_DQBUF")?;
        let Some(&(ptr, len)) = self.buffers.get(buf.index as usize) else {
            return Err(DeviceError::io(
                &self.node,
                "VIDIOC_DQBUF",
                std::io::Error::other(format!("unknown buffer index {}", buf.index)),
            ));
        };
        self.held = Some(buf.index);
        let used = (buf.bytesused as usize).min(len);
        // SAFETY: the mapping is `len` bytes, alive until Drop; the driver does not write
        // a dequeued buffer until it is queued again (next call).
        let bytes = unsafe { std::slice::from_raw_parts(ptr, used) };
        let ts = buf.timestamp;
        Ok(Some(Filled {
            bytes,
            timestamp_ns: (ts.tv_sec.max(0) as u64) * 1_000_000_000 + (ts.tv_usec.max(0) as u64) * 1_000,
            flags: buf.flags,
        }))
    }
}

impl Drop for MmapStream {
    fn drop(&mut self) {
        // Errors here (an unplugged camera answers ENODEV) leave nothing to undo.
        let mut typ = Type::VideoCapture as u32;
        let _ = self.ioctl(v4l2::vidioc::VIDIOC_STREAMOFF, &mut typ, "VIDIOC_STREAMOFF");
        for &(ptr, len) in &self.buffers {
            // SAFETY: each pair is a live mapping made in `start`, unmapped once.
            let _ = unsafe { v4l2::munmap(ptr.cast(), len) };
        }
    }
}
