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

use std::collections::HashMap;
use std::fmt;
use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use crate::camera::{Intrinsics, StereoRig};

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

/// A number read from the file, with where it came from.
#[derive(Debug, Clone, Copy)]
struct Value {
    value: f64,
    line: usize,
}

/// One `key=value` line (key and section upper-cased).
struct Entry<'a> {
    section: Option<String>,
    key: String,
    raw_key: &'a str,
    value: &'a str,
    line: usize,
}

const INTRINSIC_KEYS: [&str; 9] = ["fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3"];
const STEREO_KEYS: [&str; 6] = ["BASELINE", "TY", "TZ", "CV", "RX", "RZ"];

fn cam_section(side: &str, res: Resolution) -> String {
    format!("{side}_CAM_{}", res.name())
}

fn is_stereo_key(key: &str) -> bool {
    if STEREO_KEYS[..3].contains(&key) {
        return true;
    }
    key.split_once('_')
        .is_some_and(|(base, suffix)| STEREO_KEYS.contains(&base) && Resolution::ALL.iter().any(|r| r.name() == suffix))
}

fn is_known_section(name: &str) -> bool {
    name == "STEREO"
        || Resolution::ALL
            .iter()
            .any(|&r| name == cam_section("LEFT", r) || name == cam_section("RIGHT", r))
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

/// What one line of the file is.
enum Line<'a> {
    /// Blank or only a comment.
    Blank,
    /// `[NAME]`, the name upper-cased.
    Section(String),
    /// `key=value`, both trimmed.
    Entry { key: &'a str, value: &'a str },
    /// Anything else.
    Bad,
}

impl<'a> Line<'a> {
    fn classify(raw_line: &'a str) -> Line<'a> {
        let content = raw_line.find(['#', ';']).map_or(raw_line, |at| &raw_line[..at]).trim();
        if content.is_empty() {
            return Line::Blank;
        }
        let header = content
            .strip_prefix('[')
            .and_then(|s| s.strip_suffix(']'))
            .map(str::trim)
            .filter(|s| !s.is_empty() && !s.contains(['[', ']']));
        if let Some(name) = header {
            return Line::Section(name.to_ascii_uppercase());
        }
        match content.split_once('=') {
            Some((key, value)) if !key.trim().is_empty() && !content.starts_with('[') => Line::Entry {
                key: key.trim(),
                value: value.trim(),
            },
            _ => Line::Bad,
        }
    }
}

/// The file sorted into sections and entries.
struct Scanned<'a> {
    /// Section names (upper-cased) in order of first appearance.
    sections: Vec<String>,
    entries: Vec<Entry<'a>>,
}

/// Pass 1, syntax. A file without any calibration section is reported as such rather
/// than by its first bad line: it is most likely not a calibration file at all.
fn scan<'a>(text: &'a str, path: &Path) -> Result<Scanned<'a>, CalibrationError> {
    let mut scanned = Scanned {
        sections: Vec::new(),
        entries: Vec::new(),
    };
    let mut section: Option<String> = None;
    let mut syntax_error = None;
    for (i, raw_line) in text.lines().enumerate() {
        let line = i + 1;
        match Line::classify(raw_line) {
            Line::Blank => {}
            Line::Section(name) => {
                if !scanned.sections.contains(&name) {
                    scanned.sections.push(name.clone());
                }
                section = Some(name);
            }
            Line::Entry { key, value } => scanned.entries.push(Entry {
                section: section.clone(),
                key: key.to_ascii_uppercase(),
                raw_key: key,
                value,
                line,
            }),
            Line::Bad => {
                if syntax_error.is_none() {
                    syntax_error = Some(CalibrationError::Syntax {
                        path: path.to_path_buf(),
                        line,
                        text: raw_line.trim().chars().take(60).collect(),
                    });
                }
            }
        }
    }
    if !scanned.sections.iter().any(|s| is_known_section(s)) {
        return Err(CalibrationError::NotCalibration {
            path: path.to_path_buf(),
        });
    }
    match syntax_error {
        Some(e) => Err(e),
        None => Ok(scanned),
    }
}

/// Numbers read from the file by (section, key), both upper-cased.
type Values = HashMap<(String, String), Value>;

/// Pass 2: the numbers of the keys photopose uses, in file order; other keys and
/// sections are not looked at. A key may appear once per section.
fn read_values(entries: &[Entry<'_>], path: &Path) -> Result<Values, CalibrationError> {
    let mut values = Values::new();
    for e in entries {
        let Some(sec) = e.section.as_deref() else {
            continue;
        };
        let used = if sec == "STEREO" {
            is_stereo_key(&e.key)
        } else {
            is_known_section(sec) && INTRINSIC_KEYS.iter().any(|k| k.eq_ignore_ascii_case(&e.key))
        };
        if !used {
            continue;
        }
        let value = e.number(path)?;
        let slot = (sec.to_string(), e.key.clone());
        if let Some(first) = values.get(&slot) {
            return Err(CalibrationError::DuplicateKey {
                path: path.to_path_buf(),
                line: e.line,
                key: e.raw_key.to_string(),
                section: sec.to_string(),
                first_line: first.line,
            });
        }
        values.insert(slot, Value { value, line: e.line });
    }
    Ok(values)
}

impl Entry<'_> {
    /// The value as a finite number, positive for focal lengths and the baseline.
    fn number(&self, path: &Path) -> Result<f64, CalibrationError> {
        let value: f64 = self.value.parse().map_err(|_| CalibrationError::NotANumber {
            path: path.to_path_buf(),
            line: self.line,
            key: self.raw_key.to_string(),
            value: self.value.to_string(),
        })?;
        if !value.is_finite() {
            return Err(CalibrationError::NotFinite {
                path: path.to_path_buf(),
                line: self.line,
                key: self.raw_key.to_string(),
                value: self.value.to_string(),
            });
        }
        let positive = matches!(self.key.as_str(), "FX" | "FY") || self.key.starts_with("BASELINE");
        if positive && value <= 0.0 {
            return Err(CalibrationError::NotPositive {
                path: path.to_path_buf(),
                line: self.line,
                key: self.raw_key.to_string(),
                value,
            });
        }
        Ok(value)
    }
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
                    Some(res) if width_per_eye % 2 == 0 => format!(
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
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Point3};

    fn data(rel: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
    }

    fn example() -> Calibration {
        Calibration::load(&data("config/SN-example.conf")).unwrap()
    }

    fn fixture(name: &str) -> Result<Calibration, CalibrationError> {
        Calibration::load(&data(&format!("tests/data/calibration/{name}")))
    }

    /// The right camera's centre in the left frame, recovered from `right_from_left`.
    fn centre(rig: &StereoRig) -> Vector3<f64> {
        rig.right_from_left.inverse().translation.vector
    }

    const SIMPLE: &str = "[LEFT_CAM_HD]\nfx=700\nfy=700\ncx=640\ncy=360\nk1=0\nk2=0\np1=0\np2=0\nk3=0\n\
        [RIGHT_CAM_HD]\nfx=700\nfy=700\ncx=640\ncy=360\nk1=0\nk2=0\np1=0\np2=0\n\
        [STEREO]\nBaseline=120\nTY=0\nTZ=0\nCV_HD=0\nRX_HD=0\nRZ_HD=0\n";

    fn simple_with(from: &str, to: &str) -> Result<Calibration, CalibrationError> {
        assert!(SIMPLE.contains(from), "{from}");
        Calibration::parse(&SIMPLE.replacen(from, to, 1), Path::new("SN7.conf"))
    }

    #[test]
    fn example_file_has_all_resolutions() {
        let cal = example();
        assert_eq!(cal.resolutions(), Resolution::ALL.to_vec());
        assert!(cal.source().ends_with("config/SN-example.conf"));
        let hd = cal.rig(Resolution::HD).unwrap();
        assert_eq!((hd.width, hd.height), (1280, 720));
        assert_eq!(hd.left.fx, 699.81);
        assert_eq!(hd.right.cy, 362.12);
        assert_eq!(hd.left.k3, -0.00108271);
        assert!((hd.baseline_mm() - 119.934).abs() < 0.01, "{}", hd.baseline_mm());
        let c = centre(&hd);
        assert!((c - Vector3::new(119.934, 0.0815, -0.298)).norm() < 1e-9, "{c}");
        for res in Resolution::ALL {
            let rig = cal.rig(res).unwrap();
            assert_eq!((rig.width, rig.height), res.size());
            // Focal length scales with the image width (±1 %).
            let ratio = rig.left.fx / hd.left.fx / (res.size().0 as f64 / 1280.0);
            assert!((ratio - 1.0).abs() < 0.05, "{res}: {ratio}");
        }
    }

    #[test]
    fn right_from_left_maps_right_centre_to_origin() {
        let rig = example().rig(Resolution::HD).unwrap();
        let c = Point3::new(119.934, 0.0815, -0.298);
        assert!((rig.right_from_left * c).coords.norm() < 1e-9);
    }

    #[test]
    fn point_on_left_axis_has_disparity_fb_over_z() {
        let rig = example().rig(Resolution::HD).unwrap();
        let (l, r) = rig.project_both(&Point3::new(0.0, 0.0, 700.0));
        let (l, r) = (l.unwrap(), r.unwrap());
        let disparity = (l.x - rig.left.cx) - (r.x - rig.right.cx);
        let expected = rig.left.fx * 119.934 / 700.0;
        // Lens distortion and the ~1 mrad rotation move it by < 1 px.
        assert!((disparity - expected).abs() < 1.5, "{disparity} vs {expected}");
        assert!((l.y - r.y).abs() < 6.0);

        // Without distortion and rotation it is exact.
        let rig = simple_with("", "").unwrap().rig(Resolution::HD).unwrap();
        let (l, r) = rig.project_both(&Point3::new(0.0, 0.0, 700.0));
        assert!((l.unwrap().x - r.unwrap().x - 120.0).abs() < 1e-9);
    }

    #[test]
    fn rodrigues_matches_hand_computation() {
        let r = rodrigues(Vector3::new(0.0, std::f64::consts::FRAC_PI_2, 0.0));
        assert!((r * Vector3::x() - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-12);
        assert!((r * Vector3::z() - Vector3::x()).norm() < 1e-12);

        // R = I + sinθ·K + (1 − cosθ)·K² for unit axis k.
        let v: Vector3<f64> = Vector3::new(0.3, -0.2, 0.1);
        let theta = v.norm();
        let k = v / theta;
        let kx = Matrix3::new(0.0, -k.z, k.y, k.z, 0.0, -k.x, -k.y, k.x, 0.0);
        let hand = Matrix3::identity() + kx * theta.sin() + kx * kx * (1.0 - theta.cos());
        let got = rodrigues(v).to_rotation_matrix().into_inner();
        assert!((got - hand).norm() < 1e-12);
    }

    #[test]
    fn rotation_vector_order_is_rx_cv_rz() {
        // CV is the rotation about y: R maps x → −z, so Rᵀ (right_from_left) maps x → z.
        let cal = simple_with("CV_HD=0", "CV_HD=1.5707963267948966").unwrap();
        let rig = cal.rig(Resolution::HD).unwrap();
        let rot = rig.right_from_left.rotation;
        assert!((rot * Vector3::x() - Vector3::z()).norm() < 1e-12);
        // X_R = Rᵀ(X_L − c): the left origin lands at −Rᵀc = −(0, 0, 120).
        let origin = rig.right_from_left * Point3::origin();
        assert!(
            (origin.coords - Vector3::new(0.0, 0.0, -120.0)).norm() < 1e-9,
            "{origin}"
        );
    }

    #[test]
    fn suffixed_keys_win_and_names_are_case_insensitive() {
        let text = std::fs::read_to_string(data("tests/data/calibration/valid-suffixed.conf")).unwrap();
        assert!(text.contains("\r\n"), "fixture must keep CRLF line endings");
        let cal = fixture("valid-suffixed.conf").unwrap();
        assert_eq!(cal.resolutions(), vec![Resolution::FHD, Resolution::HD]);
        let hd = cal.rig(Resolution::HD).unwrap();
        assert!((centre(&hd) - Vector3::new(120.0, 0.08, -0.3)).norm() < 1e-9);
        let fhd = cal.rig(Resolution::FHD).unwrap();
        assert!((centre(&fhd) - Vector3::new(120.0, 0.5, -0.5)).norm() < 1e-9);
        assert_eq!(hd.left.fx, 700.5);
        assert_eq!(hd.right.fx, 701.5);
        assert_eq!(hd.right.cx, 638.5);
        assert_eq!(hd.right.k3, 0.0);
        let expected = rodrigues(Vector3::new(-0.0006, 0.002, 0.0003)).inverse();
        assert!(hd.right_from_left.rotation.angle_to(&expected) < 1e-12);
    }

    #[test]
    fn hd_only_file_serves_hd_and_explains_others() {
        let cal = fixture("valid-hd-only.conf").unwrap();
        assert_eq!(cal.resolutions(), vec![Resolution::HD]);
        assert_eq!(cal.rig_for_image(1280, 720).unwrap().left.fx, 699.81);
        let msg = cal.rig(Resolution::FHD).unwrap_err().to_string();
        assert!(
            msg.ends_with("valid-hd-only.conf: no calibration for FHD (file has HD)"),
            "{msg}"
        );
    }

    #[test]
    fn resolution_from_image_size() {
        for res in Resolution::ALL {
            let (w, h) = res.size();
            assert_eq!(Resolution::from_size(w, h), Some(res));
            assert_eq!(example().rig_for_image(w, h).unwrap().width, w);
        }
        assert_eq!(Resolution::from_size(720, 1280), None);
        for (name, res) in [
            ("2K", Resolution::R2K),
            ("hd2k", Resolution::R2K),
            ("Fhd", Resolution::FHD),
            ("HD1080", Resolution::FHD),
            (" hd ", Resolution::HD),
            ("HD720", Resolution::HD),
            ("vga", Resolution::VGA),
        ] {
            assert_eq!(Resolution::from_name(name), Some(res), "{name}");
        }
        assert!(Resolution::ALL
            .iter()
            .all(|&r| Resolution::from_name(r.name()) == Some(r)));
        assert_eq!(Resolution::from_name("8K"), None);
        let cal = Calibration::parse(SIMPLE, Path::new("SN12345.conf")).unwrap();
        assert_eq!(
            cal.rig_for_image(1000, 500).unwrap_err().to_string(),
            "SN12345.conf: image size 1000x500 per eye matches no ZED resolution \
             (2K 2208x1242, FHD 1920x1080, HD 1280x720, VGA 672x376)"
        );
        let msg = cal.rig_for_image(2560, 720).unwrap_err().to_string();
        assert!(msg.contains("side-by-side") && msg.contains("HD 1280x720"), "{msg}");
        assert_eq!(
            cal.rig(Resolution::FHD).unwrap_err().to_string(),
            "SN12345.conf: no calibration for FHD (file has HD)"
        );
    }

    #[test]
    fn invalid_fixtures_name_file_and_problem() {
        for (name, problem) in [
            (
                "invalid-not-a-number.conf",
                "line 2: value \"abc\" for key fx is not a number",
            ),
            ("invalid-missing-key.conf", "section [LEFT_CAM_HD] lacks key cy"),
            ("invalid-no-sections.conf", "not a ZED calibration file"),
            (
                "invalid-nan.conf",
                "line 17: value \"nan\" for key k1 is not a finite number",
            ),
        ] {
            let msg = fixture(name).unwrap_err().to_string();
            assert!(msg.contains(name) && msg.contains(problem), "{name}: {msg}");
            assert!(!msg.contains('\n'), "{msg}");
        }
    }

    #[test]
    fn other_problems_have_clear_messages() {
        let cases = [
            (
                simple_with("fy=700", "fy=0"),
                "SN7.conf: line 3: value 0 for key fy must be positive",
            ),
            (
                simple_with("Baseline=120", "Baseline=-120"),
                "line 21: value -120 for key Baseline must be positive",
            ),
            (
                simple_with("CV_HD=0", "CV_HD=inf"),
                "value \"inf\" for key CV_HD is not a finite number",
            ),
            (
                simple_with("k2=0", "k2=0\nK2=1"),
                "line 8: key K2 repeats in section [LEFT_CAM_HD] (first on line 7)",
            ),
            (simple_with("TY=0", ""), "section [STEREO] lacks key TY (or TY_HD)"),
            (simple_with("RX_HD=0", ""), "section [STEREO] lacks key RX_HD"),
            (simple_with("p2=0\nk3=0", "k3=0"), "section [LEFT_CAM_HD] lacks key p2"),
            (
                simple_with("[STEREO]", "[OTHER]"),
                "section [STEREO] is missing (needed for HD)",
            ),
            (
                simple_with("fx=700", "fx=699,81"),
                "line 2: value \"699,81\" for key fx is not a number (the decimal separator is '.')",
            ),
            (
                simple_with("fx=700", "fx=0"),
                "line 2: value 0 for key fx must be positive",
            ),
            (
                simple_with("fx=700", "fx 700"),
                "line 2: expected `key=value` or `[SECTION]`, found \"fx 700\"",
            ),
            (
                simple_with("[RIGHT_CAM_HD]", "[RIGHT_CAM_FHD]"),
                "no resolution is calibrated for both eyes",
            ),
            (
                Calibration::parse("", Path::new("SN7.conf")),
                "SN7.conf: not a ZED calibration file",
            ),
        ];
        for (result, problem) in cases {
            let msg = result.unwrap_err().to_string();
            assert!(msg.contains("SN7.conf") && msg.contains(problem), "{problem}: {msg}");
        }
        let cal = simple_with("", "[LEFT_CAM_VGA]\nfx=1\n").unwrap();
        let msg = cal.rig(Resolution::VGA).unwrap_err().to_string();
        assert_eq!(
            msg,
            "SN7.conf: no calibration for VGA: section [RIGHT_CAM_VGA] is missing (file has HD)"
        );
    }

    #[test]
    fn tolerates_extra_keys_sections_comments_and_bom() {
        let text = format!(
            "\u{feff}; header\n[MISC]\nSensor_ID=1\nwhatever=x\n[LEFT_CAM_FHD1200]\nfx=oops\n{}",
            SIMPLE.replace("k1=0", "k1 = 0 ; c\nk4=7\ns1=x\ntx=1")
        );
        let cal = Calibration::parse(&text, Path::new("a.conf")).unwrap();
        assert_eq!(cal.resolutions(), vec![Resolution::HD]);
    }

    #[test]
    fn missing_file_error() {
        let msg = Calibration::load(Path::new("/nonexistent/SN1.conf"))
            .unwrap_err()
            .to_string();
        assert_eq!(msg, "cannot read /nonexistent/SN1.conf: No such file or directory");
    }

    #[test]
    fn never_panics_on_damaged_input() {
        let text = std::fs::read_to_string(data("config/SN-example.conf")).unwrap();
        let path = Path::new("x.conf");
        for (i, _) in text.char_indices().step_by(7) {
            let _ = Calibration::parse(&text[..i], path);
            let _ = Calibration::parse(&text[i..], path);
        }
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        for _ in 0..2000 {
            let bytes: Vec<u8> = (0..64)
                .map(|_| {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    b"[]=#;\r\n _xfkLEFT_CAM_HD.0-9e\xff"[(state % 29) as usize]
                })
                .collect();
            let _ = Calibration::parse(&String::from_utf8_lossy(&bytes), path);
        }
    }
}
