//! `[camera]` and `[hand_eye]`: which factory calibration file photopose reads, and where
//! the left camera sits relative to the robot hand (`CL_T_H`), as written (serde, every
//! field defaulted, unknown keys rejected) and validated.

use std::path::{Path, PathBuf};

use nalgebra::Isometry3;
use serde::Deserialize;

use crate::config::{unit_pose, InvalidSetting};

/// `[camera]` as written.
#[derive(Debug, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub(crate) struct RawCamera {
    /// `None`: the built-in example calibration.
    calibration: Option<PathBuf>,
}

impl RawCamera {
    /// The calibration file to read, or `None` for the built-in example: a named file is
    /// resolved against `dir`, the configuration file's directory. Without `dir` (the
    /// built-in configuration) a file named `example_name` is the built-in example.
    pub(crate) fn calibration_file(&self, dir: Option<&Path>, example_name: &Path) -> Option<PathBuf> {
        match (&self.calibration, dir) {
            (Some(c), Some(d)) => Some(d.join(c)),
            (Some(c), None) if c != example_name => Some(c.clone()),
            _ => None,
        }
    }
}

/// `[hand_eye]` as written: `CL_T_H`, hand coordinates → left-camera coordinates.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub(crate) struct RawHandEye {
    translation_mm: [f64; 3],
    rotation_wxyz: [f64; 4],
}

impl Default for RawHandEye {
    fn default() -> Self {
        Self {
            translation_mm: [0.0; 3],
            rotation_wxyz: [1.0, 0.0, 0.0, 0.0],
        }
    }
}

impl RawHandEye {
    /// `CL_T_H` if the rotation is a unit quaternion and the translation finite, else the
    /// field that is wrong.
    pub(crate) fn left_from_hand(&self) -> Result<Isometry3<f64>, InvalidSetting> {
        let invalid = |field, problem| InvalidSetting::new("hand_eye", field, problem);
        let left_from_hand =
            unit_pose(self.translation_mm, self.rotation_wxyz).map_err(|p| invalid("rotation_wxyz", p))?;
        if self.translation_mm.iter().any(|v| !v.is_finite()) {
            return Err(invalid("translation_mm", "must be finite numbers".into()));
        }
        Ok(left_from_hand)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn calibration_file_resolves_against_the_directory() {
        let example = Path::new("SN-example.conf");
        let named = RawCamera {
            calibration: Some(PathBuf::from("SN1.conf")),
        };
        assert_eq!(
            named.calibration_file(Some(Path::new("cfg")), example),
            Some(PathBuf::from("cfg/SN1.conf"))
        );
        assert_eq!(named.calibration_file(None, example), Some(PathBuf::from("SN1.conf")));
        let built_in = RawCamera {
            calibration: Some(example.to_path_buf()),
        };
        assert_eq!(built_in.calibration_file(None, example), None);
        assert_eq!(
            RawCamera::default().calibration_file(Some(Path::new("cfg")), example),
            None
        );
    }

    #[test]
    fn hand_eye_checks_rotation_then_translation() {
        let raw = RawHandEye {
            translation_mm: [f64::NAN, 0.0, 0.0],
            rotation_wxyz: [2.0, 0.0, 0.0, 0.0],
        };
        let e = raw.left_from_hand().unwrap_err().to_string();
        assert_eq!(
            e,
            "[hand_eye] rotation_wxyz: [2, 0, 0, 0] is not a unit quaternion (norm 2.0000)"
        );
        let raw = RawHandEye {
            translation_mm: [f64::NAN, 0.0, 0.0],
            ..RawHandEye::default()
        };
        let e = raw.left_from_hand().unwrap_err().to_string();
        assert_eq!(e, "[hand_eye] translation_mm: must be finite numbers");
    }
}
