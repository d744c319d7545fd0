//! Configuration: the TOML tables of `config/default.toml`, read in two stages — each
//! domain's raw serde table (every field defaulted, unknown keys rejected), then its
//! validated settings — and assembled into the [`Config`] the rest of photopose trusts.
//!
//! The tables live with their domains: `[camera]` and `[hand_eye]` in
//! [`crate::camera::settings`]; `[search]`, `[ga]`, `[robust]`, `[tracking]`, `[model]` and
//! `[fitness]` in [`crate::estimator::settings`]; `[controller]` in
//! [`crate::client::settings`]; `[detect]` in [`crate::detect::settings`]; `[realtime]` in
//! [`crate::estimator::realtime`]. This module reads the file, names it in every error,
//! and holds what the tables share: [`InvalidSetting`], the unit-quaternion pose check and
//! the location of a TOML syntax error (`toml_error`, also used for scene files).

use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use serde::Deserialize;

use crate::camera::calibration::{Calibration, CalibrationError};
use crate::camera::geometry::{is_unit_wxyz, wxyz_norm, FILE_UNIT_TOLERANCE};
use crate::camera::settings::{RawCamera, RawHandEye};
use crate::client::settings::{ControllerSettings, RawController};
use crate::detect::settings::{DetectSettings, RawDetect};
use crate::estimator::realtime::RealtimeSettings;
use crate::estimator::settings::{
    FitnessParams, GaSettings, ModelSettings, RawSearch, RobustSettings, SearchSpace, TrackingSettings,
};

/// The built-in configuration, used when no `--config` is given.
pub const DEFAULT_TOML: &str = include_str!("../config/default.toml");
/// The example factory calibration the built-in configuration refers to.
pub const EXAMPLE_CALIBRATION: &str = include_str!("../config/SN-example.conf");
const EXAMPLE_CALIBRATION_NAME: &str = "SN-example.conf";
/// Where the built-in configuration resolves relative paths other than the calibration:
/// the directory of `config/default.toml` in the source tree photopose was built from.
const BUILT_IN_DIR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/config");

/// A configuration problem, always naming the file.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file could not be read.
    #[error("cannot read {path}: {reason}")]
    Read {
        /// The configuration file.
        path: PathBuf,
        /// Why it could not be read.
        reason: std::io::Error,
    },
    /// The file is not TOML, or not the tables and keys photopose knows.
    #[error("{path}: {message}")]
    Toml {
        /// The configuration file.
        path: PathBuf,
        /// The parser's message on one line, with the line it points at.
        message: String,
    },
    /// A value photopose cannot use.
    #[error("{path}: {setting}")]
    Invalid {
        /// The configuration file.
        path: PathBuf,
        /// The table, key and problem.
        setting: InvalidSetting,
    },
    /// The calibration file it names cannot be used.
    #[error(transparent)]
    Calibration(#[from] CalibrationError),
}

/// A settings value that cannot be used, as `[table] field: problem`.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("[{table}] {field}: {problem}")]
pub struct InvalidSetting {
    /// The TOML table, e.g. `ga`.
    pub table: &'static str,
    /// The key within the table.
    pub field: &'static str,
    /// What is wrong with its value.
    pub problem: String,
}

impl InvalidSetting {
    /// The problem `problem` with key `field` of table `table`.
    pub fn new(table: &'static str, field: &'static str, problem: String) -> Self {
        Self { table, field, problem }
    }
}

/// A pose from a translation and a `[w, x, y, z]` quaternion that must be of unit
/// length; the problem otherwise.
pub(crate) fn unit_pose(t: [f64; 3], wxyz: [f64; 4]) -> Result<Isometry3<f64>, String> {
    let [w, x, y, z] = wxyz;
    if !is_unit_wxyz(wxyz, FILE_UNIT_TOLERANCE) {
        let n = wxyz_norm(wxyz);
        return Err(format!("[{w}, {x}, {y}, {z}] is not a unit quaternion (norm {n:.4})"));
    }
    let q = Quaternion::new(w, x, y, z);
    Ok(Isometry3::from_parts(
        Translation3::from(Vector3::new(t[0], t[1], t[2])),
        UnitQuaternion::from_quaternion(q),
    ))
}

/// A TOML parse error with where the parser found it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct TomlError<'a> {
    /// The parser's message (it may span lines).
    pub message: &'a str,
    /// 1-based line and column (in bytes) of the error, when the parser knows it.
    pub line_column: Option<(usize, usize)>,
}

impl TomlError<'_> {
    /// The message on one line (line breaks become `; `), then ` (line N)`: how
    /// configuration and recording files report TOML errors.
    pub(crate) fn one_line_with_line_number(&self) -> String {
        let location = match self.line_column {
            Some((line, _)) => format!(" (line {line})"),
            None => String::new(),
        };
        self.message.replace('\n', "; ") + &location
    }
}

/// Locates `error`, raised while parsing `text`, in that text.
pub(crate) fn toml_error<'a>(text: &str, error: &'a toml::de::Error) -> TomlError<'a> {
    let line_column = error.span().map(|span| {
        let before = &text[..span.start.min(text.len())];
        let line = before.matches('\n').count() + 1;
        let column = before.len() - before.rfind('\n').map_or(0, |i| i + 1) + 1;
        (line, column)
    });
    TomlError {
        message: error.message(),
        line_column,
    }
}

/// Every table of the file as written.
#[derive(Debug, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
struct RawConfig {
    camera: RawCamera,
    hand_eye: RawHandEye,
    search: RawSearch,
    ga: GaSettings,
    model: ModelSettings,
    fitness: FitnessParams,
    robust: RobustSettings,
    tracking: TrackingSettings,
    controller: RawController,
    detect: RawDetect,
    realtime: RealtimeSettings,
}

/// The validated configuration.
#[derive(Debug, Clone)]
pub struct Config {
    /// The camera's factory calibration.
    pub calibration: Calibration,
    /// The file `[camera] calibration` names; `None` for the built-in example.
    pub calibration_file: Option<PathBuf>,
    /// `CL_T_H`: hand coordinates → left-camera coordinates.
    pub left_from_hand: Isometry3<f64>,
    /// `[search]`: the GA's search space in the hand frame.
    pub search: SearchSpace,
    /// `[ga]`: the genetic algorithm.
    pub ga: GaSettings,
    /// `[robust]`: the robust mode's search strategy.
    pub robust: RobustSettings,
    /// `[tracking]`: the GA that lives across frames.
    pub tracking: TrackingSettings,
    /// `[model]`: how a photo is sampled into a photo-model.
    pub model: ModelSettings,
    /// `[fitness]`: the constants of the fitness function.
    pub fitness: FitnessParams,
    /// `[controller]`: the example visual-servo client.
    pub controller: ControllerSettings,
    /// `[detect]`: the YOLO detector.
    pub detect: DetectSettings,
    /// `[realtime]`: the estimator process's scheduling wishes.
    pub realtime: RealtimeSettings,
}

impl Config {
    /// Loads `path`, or the built-in default configuration when `None`.
    pub fn load(path: Option<&Path>) -> Result<Config, ConfigError> {
        match path {
            None => Self::parse(DEFAULT_TOML, Path::new("config/default.toml (built in)"), None),
            Some(p) => {
                let text = std::fs::read_to_string(p).map_err(|reason| ConfigError::Read {
                    path: p.to_path_buf(),
                    reason,
                })?;
                let dir = p.parent().unwrap_or(Path::new("."));
                Self::parse(&text, p, Some(dir))
            }
        }
    }

    /// Parses configuration text; `dir` resolves relative paths (`None`: the built-in
    /// configuration, with the built-in example calibration and the other paths relative
    /// to the source tree's `config/`).
    pub fn parse(text: &str, path: &Path, dir: Option<&Path>) -> Result<Config, ConfigError> {
        let raw: RawConfig = toml::from_str(text).map_err(|e| ConfigError::Toml {
            path: path.to_path_buf(),
            message: toml_error(text, &e).one_line_with_line_number(),
        })?;
        let calibration_file = raw.camera.calibration_file(dir, Path::new(EXAMPLE_CALIBRATION_NAME));
        let calibration = match &calibration_file {
            Some(path) => Calibration::load(path)?,
            None => Calibration::parse(EXAMPLE_CALIBRATION, Path::new("config/SN-example.conf"))?,
        };
        Self::validate(raw, calibration, calibration_file, dir).map_err(|setting| ConfigError::Invalid {
            path: path.to_path_buf(),
            setting,
        })
    }

    /// Validates each table into the configuration; the first problem found is the error.
    fn validate(
        raw: RawConfig,
        calibration: Calibration,
        calibration_file: Option<PathBuf>,
        dir: Option<&Path>,
    ) -> Result<Config, InvalidSetting> {
        Ok(Config {
            calibration,
            calibration_file,
            left_from_hand: raw.hand_eye.left_from_hand()?,
            search: SearchSpace::try_from(raw.search)?,
            ga: raw.ga.validate()?,
            robust: raw.robust.validate()?,
            tracking: raw.tracking.validate()?,
            model: raw.model.validate()?,
            fitness: raw.fitness.validate()?,
            controller: ControllerSettings::try_from(raw.controller)?,
            detect: raw.detect.validate(dir.unwrap_or(Path::new(BUILT_IN_DIR)))?,
            realtime: realtime(raw.realtime)?,
        })
    }
}

/// `[realtime]` if its values are usable.
fn realtime(settings: RealtimeSettings) -> Result<RealtimeSettings, InvalidSetting> {
    match settings.problem() {
        Some((field, problem)) => Err(InvalidSetting::new("realtime", field, problem)),
        None => Ok(settings),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimator::settings::Mode;

    fn fixture(name: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data/config")
            .join(name)
    }

    /// A file that leaves keys out gets the shipped defaults for them.
    #[test]
    fn keys_left_out_take_the_shipped_defaults() {
        let builtin = Config::load(None).unwrap();
        let empty = Config::parse("", Path::new("empty.toml"), None).unwrap();
        assert_eq!(empty.search, builtin.search);
        assert_eq!(empty.ga, builtin.ga);
        assert_eq!(empty.robust, builtin.robust);
        assert_eq!(empty.tracking, builtin.tracking);
    }

    #[test]
    fn built_in_default_equals_shipped_file() {
        let builtin = Config::load(None).unwrap();
        let shipped = Config::load(Some(&Path::new(env!("CARGO_MANIFEST_DIR")).join("config/default.toml"))).unwrap();
        assert_eq!(builtin.search, shipped.search);
        assert_eq!(builtin.ga, shipped.ga);
        assert_eq!(builtin.search.z_mm, [300.0, 1200.0]);
        assert_eq!(builtin.ga.population, 100);
        assert_eq!(builtin.fitness.e4, -1.9);
        assert_eq!(builtin.fitness, FitnessParams::default());
        assert_eq!(builtin.detect, shipped.detect);
        assert!(builtin.detect.model.ends_with("config/../.detect/yolov3-tiny.onnx"));
    }

    #[test]
    fn valid_fixtures_load() {
        let c = Config::load(Some(&fixture("valid-hand-eye.toml"))).unwrap();
        assert_eq!(c.ga.mode, Mode::Paper);
        assert!((c.left_from_hand.translation.vector.x - 50.0).abs() < 1e-12);
        let d = Config::load(Some(&fixture("valid-detect.toml"))).unwrap().detect;
        assert_eq!(d.model, fixture("models/yolov8n.onnx"));
        assert_eq!(d.onnxruntime, Path::new("/opt/onnxruntime/lib/libonnxruntime.so"));
        assert_eq!((d.min_score, d.iou_threshold, d.input_size), (0.4, 0.5, 640));
    }

    #[test]
    fn invalid_fixtures_name_file_and_problem() {
        for (name, needle) in [
            (
                "invalid-inverted-range.toml",
                "[search] z_mm: [900, 300] is empty or inverted",
            ),
            ("invalid-nan.toml", "[search] x_mm: [NaN, 300] must be finite"),
            (
                "invalid-unknown-key.toml",
                "unknown field `populaton`, expected one of `mode`, `population`, `generations`, `seed`, \
                 `survivors`, `crossover_rate`, `bit_mutation_rate`, `threads` (line 4)",
            ),
            ("invalid-syntax.toml", "line 3"),
            ("invalid-quaternion.toml", "not a unit quaternion"),
            ("invalid-missing-calibration.toml", "cannot read"),
            (
                "invalid-detect-score.toml",
                "[detect] min_score: 1.5 must lie in (0, 1]",
            ),
            (
                "invalid-controller-grasp.toml",
                "[controller] grasp_rotation_wxyz: [0.5, 0, 0, 0] is not a unit quaternion (norm 0.5000)",
            ),
            (
                "invalid-tracking-lost-fitness.toml",
                "[tracking] lost_fitness: 1.5 must lie in [0, min_fitness = 1]",
            ),
            (
                "invalid-robust-level-share.toml",
                "[robust] level_share: needs one non-negative share per pyramid level, not all zero",
            ),
            (
                "invalid-model-center.toml",
                "[model] center_fraction: 1.5 must lie in (0, 1]",
            ),
        ] {
            let err = Config::load(Some(&fixture(name))).unwrap_err().to_string();
            assert!(err.contains(needle), "{name}: {err}");
            assert!(err.contains(".toml") || err.contains(".conf"), "{name}: {err}");
            assert!(!err.contains('\n'), "{name}: one line: {err}");
        }
    }
}
