//! Reader for the ZED factory calibration file `SN<serial>.conf`.
//!
//! The file is INI text with one `[LEFT_CAM_<res>]` and one `[RIGHT_CAM_<res>]` section per
//! resolution (`fx fy cx cy k1 k2 p1 p2 k3`, pixels) and a `[STEREO]` section holding the pose
//! of the right camera in the left camera's frame: centre `c = [Baseline, TY, TZ]` (mm) and
//! rotation vector `[RX, CV, RZ]` (radians, per resolution). A point maps as
//! `X_R = Rᵀ·(X_L − c)`, which is [`StereoRig::right_from_left`].
//!
//! Section names and keys are case-insensitive; `#`/`;` comments, blank lines, spaces around
//! `=` and CRLF line endings are accepted; unknown sections and keys are ignored. A key with
//! a resolution suffix (`TY_HD`) wins over the plain key (`TY`) for that resolution.
//!
//! The reader is hand-written on purpose, not an INI crate: every error names the line it
//! is on (a generic reader hands back a map and the line is lost); ZED files in the field
//! suffix `[STEREO]` keys with a resolution (`TY_HD`) and vary the case of keys, so keys
//! are matched case-insensitively and a key repeated within a section is reported with
//! both lines; and a value written with a decimal comma (`699,81`, as some locales save
//! it) gets a hint rather than a bare "not a number". Keep it.

use std::fmt;
use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use crate::camera::{Intrinsics, StereoRig};

mod ini;

use ini::{cam_section, read_values, scan, Values};

/// One of the four ZED 2i video resolutions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Resolution {
    /// 2208×1242 per eye.
    R2K,
    /// 1920×1080 per eye.
    FHD,
    /// 1280×720 per eye.
    HD,
    /// 672×376 per eye.
    VGA,
}

impl Resolution {
    /// All resolutions, largest first.
    pub const ALL: [Resolution; 4] = [Resolution::R2K, Resolution::FHD, Resolution::HD, Resolution::VGA];

    /// Image size of one eye, `(width, height)` in pixels.
    pub fn size(self) -> (u32, u32) {
        match self {
            Resolution::R2K => (2208, 1242),
            Resolution::FHD => (1920, 1080),
            Resolution::HD => (1280, 720),
            Resolution::VGA => (672, 376),
        }
    }

    /// The resolution whose per-eye image is exactly `width`×`height`.
    pub fn from_size(width: u32, height: u32) -> Option<Resolution> {
        Resolution::ALL.into_iter().find(|r| r.size() == (width, height))
    }

    /// The resolution called `name`: `2K`, `FHD`, `HD` or `VGA`, or the ZED SDK's
    /// `HD2K`, `HD1080`, `HD720`; case-insensitive, surrounding spaces ignored.
    pub fn from_name(name: &str) -> Option<Resolution> {
        match name.trim().to_ascii_uppercase().as_str() {
            "2K" | "HD2K" => Some(Resolution::R2K),
            "FHD" | "HD1080" => Some(Resolution::FHD),
            "HD" | "HD720" => Some(Resolution::HD),
            "VGA" => Some(Resolution::VGA),
            _ => None,
        }
    }

    /// The name used in section and key suffixes: `"2K"`, `"FHD"`, `"HD"`, `"VGA"`.
    pub fn name(self) -> &'static str {
        match self {
            Resolution::R2K => "2K",
            Resolution::FHD => "FHD",
            Resolution::HD => "HD",
            Resolution::VGA => "VGA",
        }
    }

    fn index(self) -> usize {
        match self {
            Resolution::R2K => 0,
            Resolution::FHD => 1,
            Resolution::HD => 2,
            Resolution::VGA => 3,
        }
    }
}

impl fmt::Display for Resolution {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A problem with a calibration file; each renders as one line naming the file.
#[derive(Debug, thiserror::Error)]
pub enum CalibrationError {
    /// The file could not be read.
    #[error("cannot read {}: {reason}", .path.display())]
    Read {
        /// The calibration file.
        path: PathBuf,
        /// Why, without the OS error number.
        reason: String,
    },
    /// A line is neither `key=value`, `[SECTION]`, a comment nor blank.
    #[error("{}: line {line}: expected `key=value` or `[SECTION]`, found {text:?}", .path.display())]
    Syntax {
        /// The calibration file.
        path: PathBuf,
        /// 1-based line of the problem.
        line: usize,
        /// The line (its first 60 characters).
        text: String,
    },
    /// A calibration value does not parse as a number.
    #[error("{}: line {line}: value {value:?} for key {key} is not a number{}", .path.display(),
        if .value.contains(',') { " (the decimal separator is '.')" } else { "" })]
    NotANumber {
        /// The calibration file.
        path: PathBuf,
        /// 1-based line of the problem.
        line: usize,
        /// The key as written.
        key: String,
        /// The value as written.
        value: String,
    },
    /// A calibration value is NaN or infinite.
    #[error("{}: line {line}: value {value:?} for key {key} is not a finite number", .path.display())]
    NotFinite {
        /// The calibration file.
        path: PathBuf,
        /// 1-based line of the problem.
        line: usize,
        /// The key as written.
        key: String,
        /// The value as written.
        value: String,
    },
    /// A focal length or the baseline is zero or negative.
    #[error("{}: line {line}: value {value} for key {key} must be positive", .path.display())]
    NotPositive {
        /// The calibration file.
        path: PathBuf,
        /// 1-based line of the problem.
        line: usize,
        /// The key as written.
        key: String,
        /// The value read.
        value: f64,
    },
    /// The same key appears twice in one section.
    #[error("{}: line {line}: key {key} repeats in section [{section}] (first on line {first_line})", .path.display())]
    DuplicateKey {
        /// The calibration file.
        path: PathBuf,
        /// 1-based line of the problem.
        line: usize,
        /// The key as written.
        key: String,
        /// The section, upper-cased.
        section: String,
        /// Where the key first appeared.
        first_line: usize,
    },
    /// No `[LEFT_CAM_*]`, `[RIGHT_CAM_*]` or `[STEREO]` section at all.
    #[error(
        "{}: not a ZED calibration file (no [LEFT_CAM_<res>], [RIGHT_CAM_<res>] or [STEREO] section)",
        .path.display()
    )]
    NotCalibration {
        /// The calibration file.
        path: PathBuf,
    },
    /// A section needed for a calibrated resolution lacks a required key.
    #[error("{}: section [{section}] lacks key {key}", .path.display())]
    MissingKey {
        /// The calibration file.
        path: PathBuf,
        /// The section, upper-cased.
        section: String,
        /// The key, with the suffixed form it may take.
        key: String,
    },
    /// A section needed by the calibrated resolutions is absent.
    #[error("{}: section [{section}] is missing (needed for {needed_for})", .path.display())]
    MissingSection {
        /// The calibration file.
        path: PathBuf,
        /// The missing section.
        section: String,
        /// The resolution that needs it.
        needed_for: String,
    },
    /// No resolution has both a left and a right camera section.
    #[error(
        "{}: no resolution is calibrated for both eyes (needs [LEFT_CAM_<res>] and [RIGHT_CAM_<res>] for one of 2K, FHD, HD, VGA)",
        .path.display()
    )]
    NoUsableResolution {
        /// The calibration file.
        path: PathBuf,
    },
    /// An image size that is none of the ZED resolutions.
    #[error(
        "{}: image size {width}x{height} per eye matches no ZED resolution (2K 2208x1242, FHD 1920x1080, HD 1280x720, VGA 672x376){hint}",
        .path.display()
    )]
    UnknownImageSize {
        /// The calibration file.
        path: PathBuf,
        /// Image width per eye, pixels.
        width: u32,
        /// Image height, pixels.
        height: u32,
        /// A hint when the size looks like a side-by-side frame, or empty.
        hint: String,
    },
    /// The requested resolution is not calibrated in this file.
    #[error("{}: no calibration for {resolution}{detail} (file has {available})", .path.display())]
    MissingResolution {
        /// The calibration file.
        path: PathBuf,
        /// The resolution asked for.
        resolution: Resolution,
        /// Which camera section is missing, when one eye is calibrated, or empty.
        detail: String,
        /// The calibrated resolutions, or "none".
        available: String,
    },
}

/// The factory calibration of one ZED camera: a [`StereoRig`] per calibrated resolution.
#[derive(Debug, Clone)]
pub struct Calibration {
    source: PathBuf,
    rigs: [Option<StereoRig>; 4],
    /// Name of the missing camera section for resolutions calibrated for one eye only.
    half: [Option<String>; 4],
}

/// `io::Error` text without the trailing ` (os error N)`.
fn io_reason(e: &std::io::Error) -> String {
    let mut s = e.to_string();
    if let Some(i) = s.find(" (os error ") {
        s.truncate(i);
    }
    s
}

/// Rotation from a rotation vector (axis × angle, radians): Rodrigues' formula.
fn rodrigues(v: Vector3<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::from_scaled_axis(v)
}

impl Calibration {
    /// Reads and parses the calibration file at `path`.
    pub fn load(path: &Path) -> Result<Calibration, CalibrationError> {
        let bytes = std::fs::read(path).map_err(|e| CalibrationError::Read {
            path: path.to_path_buf(),
            reason: io_reason(&e),
        })?;
        Self::parse(&String::from_utf8_lossy(&bytes), path)
    }

    /// Parses calibration text; `source` only names the file in messages.
    pub fn parse(text: &str, source: &Path) -> Result<Calibration, CalibrationError> {
        let path = source.to_path_buf();
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let scanned = scan(text, &path)?;
        let values = read_values(&scanned.entries, &path)?;
        Self::from_values(path, &scanned.sections, &values)
    }

    /// Pass 3: one rig per resolution calibrated for both eyes, and the missing camera
    /// section of each resolution calibrated for one eye only.
    fn from_values(path: PathBuf, sections: &[String], values: &Values) -> Result<Calibration, CalibrationError> {
        let has = |name: &str| sections.iter().any(|s| s == name);
        let mut rigs: [Option<StereoRig>; 4] = Default::default();
        let mut half: [Option<String>; 4] = Default::default();
        for res in Resolution::ALL {
            let (left, right) = (cam_section("LEFT", res), cam_section("RIGHT", res));
            match (has(&left), has(&right)) {
                (true, true) => {}
                (false, false) => continue,
                (true, false) => {
                    half[res.index()] = Some(right);
                    continue;
                }
                (false, true) => {
                    half[res.index()] = Some(left);
                    continue;
                }
            }
            if !has("STEREO") {
                return Err(CalibrationError::MissingSection {
                    path,
                    section: "STEREO".into(),
                    needed_for: res.name().into(),
                });
            }
            let reader = Reader { path: &path, values };
            rigs[res.index()] = Some(reader.rig(res, &left, &right)?);
        }
        if rigs.iter().all(Option::is_none) {
            return Err(CalibrationError::NoUsableResolution { path });
        }
        Ok(Calibration {
            source: path,
            rigs,
            half,
        })
    }

    /// The stereo rig for `res`; an error if the file does not calibrate it.
    pub fn rig(&self, res: Resolution) -> Result<StereoRig, CalibrationError> {
        if let Some(Some(rig)) = self.rigs.get(res.index()) {
            return Ok(rig.clone());
        }
        let detail = match self.half.get(res.index()) {
            Some(Some(missing)) => format!(": section [{missing}] is missing"),
            _ => String::new(),
        };
        let available: Vec<&str> = self.resolutions().iter().map(|r| r.name()).collect();
        Err(CalibrationError::MissingResolution {
            path: self.source.clone(),
            resolution: res,
            detail,
            available: if available.is_empty() {
                "none".into()
            } else {
                available.join(", ")
            },
        })
    }

    /// The stereo rig for images of `width_per_eye`×`height` pixels (one eye, not the
    /// side-by-side frame).
    pub fn rig_for_image(&self, width_per_eye: u32, height: u32) -> Result<StereoRig, CalibrationError> {
        match Resolution::from_size(width_per_eye, height) {
            Some(res) => self.rig(res),
            None => {
                let hint = match Resolution::from_size(width_per_eye / 2, height) {
                    Some(res) if width_per_eye.is_multiple_of(2) => format!(
                        "; {width_per_eye}x{height} looks like a side-by-side frame, whose per-eye size is {} {}x{height}",
                        res.name(),
                        width_per_eye / 2
                    ),
                    _ => String::new(),
                };
                Err(CalibrationError::UnknownImageSize {
                    path: self.source.clone(),
                    width: width_per_eye,
                    height,
                    hint,
                })
            }
        }
    }

    /// The calibrated resolutions, largest first.
    pub fn resolutions(&self) -> Vec<Resolution> {
        Resolution::ALL
            .into_iter()
            .filter(|r| matches!(self.rigs.get(r.index()), Some(Some(_))))
            .collect()
    }

    /// The file this calibration was read from (as given).
    pub fn source(&self) -> &Path {
        &self.source
    }
}

/// Looks up parsed values and reports missing keys.
struct Reader<'a> {
    path: &'a Path,
    values: &'a Values,
}

impl Reader<'_> {
    /// The rig of `res` from its camera sections `left` and `right` and `[STEREO]`.
    fn rig(&self, res: Resolution, left: &str, right: &str) -> Result<StereoRig, CalibrationError> {
        let (width, height) = res.size();
        Ok(StereoRig {
            width,
            height,
            left: self.intrinsics(left)?,
            right: self.intrinsics(right)?,
            right_from_left: self.extrinsics(res)?,
        })
    }

    fn get(&self, section: &str, key: &str) -> Option<f64> {
        self.values
            .get(&(section.to_string(), key.to_ascii_uppercase()))
            .map(|v| v.value)
    }

    fn require(&self, section: &str, key: &str) -> Result<f64, CalibrationError> {
        self.get(section, key).ok_or_else(|| CalibrationError::MissingKey {
            path: self.path.to_path_buf(),
            section: section.to_string(),
            key: key.to_string(),
        })
    }

    fn intrinsics(&self, section: &str) -> Result<Intrinsics, CalibrationError> {
        Ok(Intrinsics {
            fx: self.require(section, "fx")?,
            fy: self.require(section, "fy")?,
            cx: self.require(section, "cx")?,
            cy: self.require(section, "cy")?,
            k1: self.require(section, "k1")?,
            k2: self.require(section, "k2")?,
            p1: self.require(section, "p1")?,
            p2: self.require(section, "p2")?,
            k3: self.get(section, "k3").unwrap_or(0.0),
        })
    }

    /// `key_<res>` if present, else the plain `key`.
    fn stereo_either(&self, key: &str, res: Resolution) -> Result<f64, CalibrationError> {
        let suffixed = format!("{key}_{}", res.name());
        self.get("STEREO", &suffixed)
            .or_else(|| self.get("STEREO", key))
            .ok_or_else(|| CalibrationError::MissingKey {
                path: self.path.to_path_buf(),
                section: "STEREO".into(),
                key: format!("{key} (or {suffixed})"),
            })
    }

    fn extrinsics(&self, res: Resolution) -> Result<Isometry3<f64>, CalibrationError> {
        let centre = Vector3::new(
            self.stereo_either("Baseline", res)?,
            self.stereo_either("TY", res)?,
            self.stereo_either("TZ", res)?,
        );
        let suffixed = |key: &str| self.require("STEREO", &format!("{key}_{}", res.name()));
        let rotation = rodrigues(Vector3::new(suffixed("RX")?, suffixed("CV")?, suffixed("RZ")?));
        let inverse = rotation.inverse();
        Ok(Isometry3::from_parts(Translation3::from(-(inverse * centre)), inverse))
    }
}

#[cfg(test)]
mod tests;
