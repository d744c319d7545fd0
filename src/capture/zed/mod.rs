//! `--source zed`: a ZED 2i driven as a plain UVC camera through V4L2, without the ZED
//! SDK. The camera sends both eyes side by side in one YUYV 4:2:2 image, published as
//! it arrives (the estimator converts).
//!
//! Everything that does not touch the kernel compiles and is tested without the cargo
//! feature `zed`: the mode table (here), finding the camera and its calibration in sysfs
//! ([`discovery`]), the streaming and reconnect loop over the [`device::Device`] trait
//! ([`stream`]) and a scripted fake camera ([`fake`]). Only `v4l2`, the real device,
//! needs the feature (the `v4l` crate, built with bindgen and libclang).

pub mod device;
pub mod discovery;
pub mod fake;
pub mod stream;
#[cfg(feature = "zed")]
pub mod v4l2;

use std::fmt;

use crate::camera::calibration::Resolution;
use crate::capture::Geometry;
use crate::vision::PixelFormat;

/// A video mode of the ZED 2i: side-by-side YUYV at one resolution and frame rate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Mode {
    /// Resolution of each eye.
    pub resolution: Resolution,
    /// Frames per second.
    pub fps: u32,
}

/// Every mode the ZED 2i offers over UVC, largest first.
pub const MODES: [Mode; 10] = [
    Mode::new(Resolution::R2K, 15),
    Mode::new(Resolution::FHD, 15),
    Mode::new(Resolution::FHD, 30),
    Mode::new(Resolution::HD, 15),
    Mode::new(Resolution::HD, 30),
    Mode::new(Resolution::HD, 60),
    Mode::new(Resolution::VGA, 15),
    Mode::new(Resolution::VGA, 30),
    Mode::new(Resolution::VGA, 60),
    Mode::new(Resolution::VGA, 100),
];

/// The mode of `--source zed` without `--resolution` and `--fps`.
pub const DEFAULT_MODE: Mode = Mode::new(Resolution::HD, 60);

/// A mode that cannot be used.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ModeError {
    /// `--resolution` names no ZED resolution.
    #[error("unknown --resolution {0:?}: use 2K, FHD, HD or VGA")]
    UnknownResolution(String),
    /// The ZED 2i has no such resolution and frame rate.
    #[error("the ZED 2i has no {resolution} mode at {fps} fps; valid modes: {}", mode_list(&MODES))]
    Unsupported {
        /// The resolution asked for.
        resolution: Resolution,
        /// The frame rate asked for, as given.
        fps: String,
    },
}

impl Mode {
    /// The mode of `resolution` at `fps`.
    pub const fn new(resolution: Resolution, fps: u32) -> Self {
        Self { resolution, fps }
    }

    /// The mode of `--resolution` (default HD) and `--fps` (default: the fastest of the
    /// resolution), refused with the list of valid modes when the camera has no such mode.
    pub fn select(resolution: Option<&str>, fps: Option<f64>) -> Result<Mode, ModeError> {
        let resolution = match resolution {
            None => DEFAULT_MODE.resolution,
            Some(name) => parse_resolution(name)?,
        };
        let mut offered = MODES.iter().filter(|m| m.resolution == resolution);
        let found = match fps {
            None => offered.next_back(),
            Some(f) => offered.into_iter().find(|m| m.fps as f64 == f),
        };
        found.copied().ok_or_else(|| ModeError::Unsupported {
            resolution,
            fps: fps.map_or_else(String::new, |f| f.to_string()),
        })
    }

    /// The side-by-side YUYV frames of this mode.
    pub fn geometry(self) -> Geometry {
        let (width, height) = self.resolution.size();
        Geometry {
            width,
            height,
            format: PixelFormat::Yuyv,
        }
    }
}

impl fmt::Display for Mode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (w, h) = self.resolution.size();
        write!(f, "{} (2×{w}×{h}) at {} fps", self.resolution, self.fps)
    }
}

/// `2K`, `FHD`, `HD`, `VGA` (case-insensitive).
pub fn parse_resolution(name: &str) -> Result<Resolution, ModeError> {
    Resolution::ALL
        .into_iter()
        .find(|r| r.name().eq_ignore_ascii_case(name.trim()))
        .ok_or_else(|| ModeError::UnknownResolution(name.to_string()))
}

/// Modes grouped by resolution: `2K@15, FHD@15/30, HD@15/30/60`.
pub fn mode_list(modes: &[Mode]) -> String {
    let mut out: Vec<String> = Vec::new();
    for r in Resolution::ALL {
        let rates: Vec<String> = modes
            .iter()
            .filter(|m| m.resolution == r)
            .map(|m| m.fps.to_string())
            .collect();
        if !rates.is_empty() {
            out.push(format!("{r}@{}", rates.join("/")));
        }
    }
    if out.is_empty() {
        "none".into()
    } else {
        out.join(", ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mode_table_is_the_zed_2i_one() {
        assert_eq!(mode_list(&MODES), "2K@15, FHD@15/30, HD@15/30/60, VGA@15/30/60/100");
        let g = Mode::new(Resolution::R2K, 15).geometry();
        assert_eq!((g.width, g.height, g.format), (2208, 1242, PixelFormat::Yuyv));
        assert_eq!(g.row_stride(), 2 * 2208 * 2);
        assert_eq!(DEFAULT_MODE.to_string(), "HD (2×1280×720) at 60 fps");
    }

    #[test]
    fn modes_are_selected_or_refused_with_the_valid_list() {
        assert_eq!(Mode::select(None, None), Ok(Mode::new(Resolution::HD, 60)));
        assert_eq!(Mode::select(Some("vga"), None), Ok(Mode::new(Resolution::VGA, 100)));
        assert_eq!(Mode::select(Some("2K"), None), Ok(Mode::new(Resolution::R2K, 15)));
        assert_eq!(
            Mode::select(Some("FHD"), Some(15.0)),
            Ok(Mode::new(Resolution::FHD, 15))
        );
        assert_eq!(Mode::select(None, Some(30.0)), Ok(Mode::new(Resolution::HD, 30)));
        let e = Mode::select(Some("2K"), Some(30.0)).unwrap_err().to_string();
        assert_eq!(
            e,
            "the ZED 2i has no 2K mode at 30 fps; valid modes: 2K@15, FHD@15/30, HD@15/30/60, VGA@15/30/60/100"
        );
        let e = Mode::select(Some("HD"), Some(59.94)).unwrap_err().to_string();
        assert!(e.contains("no HD mode at 59.94 fps"), "{e}");
        let e = Mode::select(Some("4K"), None).unwrap_err().to_string();
        assert_eq!(e, "unknown --resolution \"4K\": use 2K, FHD, HD or VGA");
    }
}
