//! Configuration: the TOML tables of `config/default.toml`, parsed in two stages —
//! raw serde structs (every field defaulted, unknown keys rejected), then a validated
//! [`Config`] the rest of photopose trusts.

use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use serde::Deserialize;

use crate::camera::calibration::{Calibration, CalibrationError};
use crate::camera::geometry::{is_unit_wxyz, wxyz_norm, FILE_UNIT_TOLERANCE};
use crate::estimator::realtime::RealtimeSettings;
use crate::vision::color::ColorClasses;

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
    #[error("cannot read {path}: {source}")]
    Read { path: PathBuf, source: std::io::Error },
    #[error("{path}: {message}")]
    Toml { path: PathBuf, message: String },
    #[error("{path}: [{table}] {field}: {problem}")]
    Invalid {
        path: PathBuf,
        table: &'static str,
        field: &'static str,
        problem: String,
    },
    #[error(transparent)]
    Calibration(#[from] CalibrationError),
}

/// Which method the estimator runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    /// The paper taken literally: binary GA, raw-hue outer test.
    Paper,
    /// Colour-class aware outer test, coarse-to-fine real-valued GA with local refinement.
    Robust,
}

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

#[derive(Debug, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
struct RawCamera {
    /// `None`: the built-in example calibration.
    calibration: Option<PathBuf>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, default)]
struct RawHandEye {
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

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, default)]
struct RawSearch {
    x_mm: [f64; 2],
    y_mm: [f64; 2],
    z_mm: [f64; 2],
    size_mm: [f64; 2],
    aspect_k: [f64; 2],
}

impl Default for RawSearch {
    fn default() -> Self {
        Self {
            x_mm: [-300.0, 300.0],
            y_mm: [-300.0, 300.0],
            z_mm: [300.0, 1200.0],
            size_mm: [20.0, 400.0],
            aspect_k: [0.5, 2.0],
        }
    }
}

/// GA search space in the hand frame (`[search]`), validated: every range finite and
/// increasing, depth and sizes positive.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SearchSpace {
    pub x_mm: [f64; 2],
    pub y_mm: [f64; 2],
    pub z_mm: [f64; 2],
    /// Range of the model length `L`; with the photo's `L_P` it gives the range of α.
    pub size_mm: [f64; 2],
    /// Range of `k = β/α`.
    pub aspect_k: [f64; 2],
}

/// `[ga]`: the genetic algorithm.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GaSettings {
    pub mode: Mode,
    pub population: usize,
    pub generations: usize,
    pub seed: u64,
    /// Fraction of the population that survives each generation unchanged (sorted best first).
    pub survivors: f64,
    /// Probability that a child is made by crossover (else it is a mutated copy).
    pub crossover_rate: f64,
    /// Paper mode: probability of flipping each bit of a child.
    pub bit_mutation_rate: f64,
    /// Worker threads for fitness evaluation; 0 = one per core.
    pub threads: usize,
}

impl GaSettings {
    /// How many of the population survive each generation (at least 1, at most all but 1).
    pub fn survivor_count(&self) -> usize {
        ((self.population as f64 * self.survivors).round() as usize).clamp(1, self.population.saturating_sub(1).max(1))
    }
}

impl Default for GaSettings {
    fn default() -> Self {
        Self {
            mode: Mode::Robust,
            population: 100,
            generations: 1000,
            seed: 1,
            survivors: 0.2,
            crossover_rate: 0.7,
            bit_mutation_rate: 0.02,
            threads: 0,
        }
    }
}

/// `[robust]`: the default mode's search strategy.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RobustSettings {
    /// Image pyramid levels (1 = full resolution only); level `l` halves the images `l` times.
    pub pyramid_levels: usize,
    /// Share of the generations spent on each level, coarsest first (normalised).
    pub level_share: Vec<f64>,
    /// Independent populations started on the coarsest level; the best continues.
    pub restarts: usize,
    /// Each coarse population starts as the best of `prior_samples × population`
    /// view-prior candidates.
    pub prior_samples: usize,
    /// Fraction of each new generation that is random immigrants on the coarsest level.
    pub immigrants: f64,
    /// Evaluations of the final local refinement at full resolution.
    pub refine_evaluations: usize,
    /// Minimum |cos| between the card normal and the line of sight (edge-on guard).
    pub min_facing_cos: f64,
    /// A chromatic inner point also needs its saturation within this of the stored one.
    pub sat_tolerance: u8,
    /// Smallest image extent of a model side, full-resolution pixels (degenerate-pose guard).
    pub min_extent_px: f64,
    /// Weight of stereo confirmation in the search's ranking: the share of inner points
    /// that match the model in the left image and whose right pixel shows the same
    /// colour. 0 ranks by `F` alone.
    pub stereo_weight: f64,
}

impl Default for RobustSettings {
    fn default() -> Self {
        Self {
            pyramid_levels: 3,
            level_share: vec![0.5, 0.25, 0.25],
            restarts: 4,
            prior_samples: 20,
            immigrants: 0.1,
            refine_evaluations: 3000,
            min_facing_cos: 0.3,
            sat_tolerance: 50,
            min_extent_px: 24.0,
            stereo_weight: 0.5,
        }
    }
}

/// `[tracking]`: the GA that lives across frames (the estimator process).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrackingSettings {
    /// Individuals kept from frame to frame.
    pub population: usize,
    /// Generations run on each frame.
    pub generations_per_frame: usize,
    /// 1: every model point; 2: one point per 2×2 block of the grid, with the block's mean
    /// colour (a quarter of the work).
    pub point_stride: usize,
    /// Fitness threads of a tracking frame (0: one per core). A frame's work is small:
    /// waking other threads for each generation can cost more than it saves.
    pub threads: usize,
    /// Gaussian mutation step, in normalised gene units.
    pub sigma: f64,
    /// Below this `F` the object counts as not tracked (status `searching`).
    pub min_fitness: f64,
    /// The floor: a pose whose `F` is below this is published as `lost`, never
    /// `tracking` or `searching` (0 ≤ `lost_fitness` ≤ `min_fitness`).
    pub lost_fitness: f64,
    /// Below this share of the best `F` since the object was acquired the object counts
    /// as not tracked either: a model that slipped onto part of its target scores well
    /// above `min_fitness` but far below what the whole target gave.
    pub min_fitness_share: f64,
    /// Share of each generation replaced by view-prior immigrants while searching.
    pub immigrants: f64,
    /// Frames of searching before the object is `lost` and acquired afresh.
    pub lost_after_frames: usize,
    /// Generations of the one-shot robust search that (re)acquires the object.
    pub acquire_generations: usize,
}

impl Default for TrackingSettings {
    fn default() -> Self {
        Self {
            population: 40,
            generations_per_frame: 6,
            point_stride: 2,
            threads: 1,
            sigma: 0.003,
            min_fitness: 1.0,
            lost_fitness: 0.5,
            min_fitness_share: 0.85,
            immigrants: 0.2,
            lost_after_frames: 30,
            acquire_generations: 300,
        }
    }
}

/// `[model]`: how `photopose model` samples the photo.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ModelSettings {
    /// Grid step in photo pixels; 0 chooses it so the box holds about `target_points`.
    pub step_px: f64,
    pub target_points: usize,
    /// Width of the outer strip in photo pixels; 0 = 15 % of the box's shorter side.
    pub outer_width_px: f64,
    /// Size of the central rectangle (paper's BECG) whose mean hue is `H̄_in`, as a
    /// fraction of the box.
    pub center_fraction: f64,
}

impl Default for ModelSettings {
    fn default() -> Self {
        Self {
            step_px: 0.0,
            target_points: 1800,
            outer_width_px: 0.0,
            center_fraction: 0.5,
        }
    }
}

/// `[fitness]`: the constants of eqs. 12–18 and Table 1.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FitnessParams {
    pub e1: f64,
    pub e2: f64,
    pub e3: f64,
    pub e4: f64,
    /// Outer point: `|H_I − H̄_in| ≥ outer_hue_threshold` is background (eq. 16).
    pub outer_hue_threshold: u8,
    /// Inner point of an "other" colour: close when the hues differ by at most this.
    pub inner_hue_tolerance: u8,
    pub mu: f64,
    pub sigma: f64,
    /// Table 1: `V ≤ black_v_max` is black.
    pub black_v_max: u8,
    /// Table 1: `S ≤ achromatic_s_max` (not black) is gray or white.
    pub achromatic_s_max: u8,
    /// Table 1: an achromatic colour with `V ≥ white_v_min` is white.
    pub white_v_min: u8,
}

impl FitnessParams {
    /// The colour classes of Table 1 with these thresholds.
    pub fn classes(&self) -> ColorClasses {
        ColorClasses {
            black_v_max: self.black_v_max,
            achromatic_s_max: self.achromatic_s_max,
            white_v_min: self.white_v_min,
        }
    }
}

impl Default for FitnessParams {
    fn default() -> Self {
        Self {
            e1: 2.0,
            e2: -0.5,
            e3: 0.5,
            e4: -1.9,
            outer_hue_threshold: 15,
            inner_hue_tolerance: 15,
            mu: 1.0,
            sigma: 0.08,
            black_v_max: 45,
            achromatic_s_max: 30,
            white_v_min: 221,
        }
    }
}

/// `[controller]` as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, default)]
struct RawController {
    rate_hz: f64,
    deadline_ms: f64,
    gain: f64,
    max_speed_mm_s: f64,
    max_turn_deg_s: f64,
    grasp_position_mm: [f64; 3],
    grasp_rotation_wxyz: [f64; 4],
}

impl Default for RawController {
    fn default() -> Self {
        Self {
            rate_hz: 200.0,
            deadline_ms: 100.0,
            gain: 1.5,
            max_speed_mm_s: 150.0,
            max_turn_deg_s: 30.0,
            grasp_position_mm: [0.0, 0.0, 150.0],
            grasp_rotation_wxyz: [1.0, 0.0, 0.0, 0.0],
        }
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, default)]
struct RawDetect {
    model: PathBuf,
    onnxruntime: PathBuf,
    min_score: f32,
    iou_threshold: f32,
    input_size: u32,
    threads: usize,
}

impl Default for RawDetect {
    fn default() -> Self {
        Self {
            model: PathBuf::from("../.detect/yolov3-tiny.onnx"),
            onnxruntime: PathBuf::from("../.detect/onnxruntime/libonnxruntime.so.1.31.1"),
            min_score: 0.25,
            iou_threshold: 0.45,
            input_size: 640,
            threads: 0,
        }
    }
}

/// `[controller]`: the example visual-servo client (`photopose controller`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ControllerSettings {
    /// Commands per second.
    pub rate_hz: f64,
    /// A pose whose frame was captured longer ago than this is stale.
    pub deadline: std::time::Duration,
    /// λ of the servo law, 1/s.
    pub gain: f64,
    /// Speed limits, mm/s and rad/s.
    pub max_speed_mm_s: f64,
    pub max_turn_rad_s: f64,
    /// The object's pose in the hand frame at which the hand may grasp it.
    pub hand_from_grasp: Isometry3<f64>,
}

/// `[detect]`: the YOLO detector of `photopose model` (cargo feature `detect`).
#[derive(Debug, Clone, PartialEq)]
pub struct DetectSettings {
    /// The YOLO network (.onnx), resolved against the configuration file's directory.
    pub model: PathBuf,
    /// The ONNX Runtime shared library (≥ 1.31), resolved likewise; `ORT_DYLIB_PATH`
    /// overrides it.
    pub onnxruntime: PathBuf,
    /// Detections scoring below this (0–1) are dropped.
    pub min_score: f32,
    /// Per-class NMS: of two boxes overlapping by more than this IoU the weaker goes.
    pub iou_threshold: f32,
    /// Input side for networks whose input size is not fixed (a multiple of 32).
    pub input_size: u32,
    /// ONNX Runtime intra-op threads, 0 = its default (one per core).
    pub threads: usize,
}

/// The validated configuration.
#[derive(Debug, Clone)]
pub struct Config {
    pub calibration: Calibration,
    /// The file `[camera] calibration` names; `None` for the built-in example.
    pub calibration_file: Option<PathBuf>,
    /// `CL_T_H`: hand coordinates → left-camera coordinates.
    pub left_from_hand: Isometry3<f64>,
    pub search: SearchSpace,
    pub ga: GaSettings,
    pub robust: RobustSettings,
    pub tracking: TrackingSettings,
    pub model: ModelSettings,
    pub fitness: FitnessParams,
    pub controller: ControllerSettings,
    pub detect: DetectSettings,
    pub realtime: RealtimeSettings,
}

impl Config {
    /// Loads `path`, or the built-in default configuration when `None`.
    pub fn load(path: Option<&Path>) -> Result<Config, ConfigError> {
        match path {
            None => Self::parse(DEFAULT_TOML, Path::new("config/default.toml (built in)"), None),
            Some(p) => {
                let text = std::fs::read_to_string(p).map_err(|source| ConfigError::Read {
                    path: p.to_path_buf(),
                    source,
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
            message: e.message().replace('\n', "; ") + &toml_location(text, e.span()),
        })?;
        let invalid = |table, field, problem: String| ConfigError::Invalid {
            path: path.to_path_buf(),
            table,
            field,
            problem,
        };
        // No calibration named (or the built-in configuration's): the example file.
        let calibration_file = match (&raw.camera.calibration, dir) {
            (Some(c), Some(d)) => Some(d.join(c)),
            (Some(c), None) if c != Path::new(EXAMPLE_CALIBRATION_NAME) => Some(c.clone()),
            _ => None,
        };
        let calibration = match &calibration_file {
            Some(path) => Calibration::load(path)?,
            None => Calibration::parse(EXAMPLE_CALIBRATION, Path::new("config/SN-example.conf"))?,
        };
        let left_from_hand = pose(raw.hand_eye.translation_mm, raw.hand_eye.rotation_wxyz)
            .map_err(|p| invalid("hand_eye", "rotation_wxyz", p))?;
        if raw.hand_eye.translation_mm.iter().any(|v| !v.is_finite()) {
            return Err(invalid("hand_eye", "translation_mm", "must be finite numbers".into()));
        }
        let s = &raw.search;
        for (field, range, positive) in [
            ("x_mm", s.x_mm, false),
            ("y_mm", s.y_mm, false),
            ("z_mm", s.z_mm, true),
            ("size_mm", s.size_mm, true),
            ("aspect_k", s.aspect_k, true),
        ] {
            check_range(range, positive).map_err(|p| invalid("search", field, p))?;
        }
        let search = SearchSpace {
            x_mm: s.x_mm,
            y_mm: s.y_mm,
            z_mm: s.z_mm,
            size_mm: s.size_mm,
            aspect_k: s.aspect_k,
        };
        let ga = raw.ga;
        if ga.population < 4 {
            return Err(invalid(
                "ga",
                "population",
                format!("{} is too small (at least 4)", ga.population),
            ));
        }
        if !(ga.survivors > 0.0 && ga.survivors < 1.0) {
            return Err(invalid(
                "ga",
                "survivors",
                format!("{} must lie in (0, 1)", ga.survivors),
            ));
        }
        for (field, v) in [
            ("crossover_rate", ga.crossover_rate),
            ("bit_mutation_rate", ga.bit_mutation_rate),
        ] {
            if !(0.0..=1.0).contains(&v) {
                return Err(invalid("ga", field, format!("{v} must lie in [0, 1]")));
            }
        }
        let robust = raw.robust;
        if robust.pyramid_levels == 0 || robust.pyramid_levels > 5 {
            return Err(invalid(
                "robust",
                "pyramid_levels",
                format!("{} must be 1 to 5", robust.pyramid_levels),
            ));
        }
        if robust.level_share.len() != robust.pyramid_levels
            || robust.level_share.iter().any(|v| !v.is_finite() || *v < 0.0)
            || robust.level_share.iter().sum::<f64>() <= 0.0
        {
            return Err(invalid(
                "robust",
                "level_share",
                "needs one non-negative share per pyramid level, not all zero".into(),
            ));
        }
        if robust.restarts == 0 {
            return Err(invalid("robust", "restarts", "must be at least 1".into()));
        }
        if !(0.0..1.0).contains(&robust.immigrants) {
            return Err(invalid(
                "robust",
                "immigrants",
                format!("{} must lie in [0, 1)", robust.immigrants),
            ));
        }
        if !(0.0..1.0).contains(&robust.min_facing_cos) {
            return Err(invalid(
                "robust",
                "min_facing_cos",
                format!("{} must lie in [0, 1)", robust.min_facing_cos),
            ));
        }
        if !(robust.stereo_weight >= 0.0 && robust.stereo_weight.is_finite()) {
            return Err(invalid(
                "robust",
                "stereo_weight",
                format!("{} must be a non-negative number", robust.stereo_weight),
            ));
        }
        let tracking = raw.tracking;
        if tracking.population < 4 {
            return Err(invalid("tracking", "population", "must be at least 4".into()));
        }
        if !(1..=8).contains(&tracking.point_stride) {
            return Err(invalid(
                "tracking",
                "point_stride",
                format!("{} must lie in 1..=8", tracking.point_stride),
            ));
        }
        if tracking.generations_per_frame == 0 || tracking.acquire_generations == 0 {
            return Err(invalid(
                "tracking",
                "generations_per_frame",
                "generations_per_frame and acquire_generations must be at least 1".into(),
            ));
        }
        if !(tracking.sigma.is_finite() && tracking.sigma > 0.0) {
            return Err(invalid("tracking", "sigma", format!("{} must be > 0", tracking.sigma)));
        }
        if !(tracking.min_fitness.is_finite() && tracking.min_fitness >= 0.0) {
            return Err(invalid(
                "tracking",
                "min_fitness",
                format!("{} must be a non-negative number", tracking.min_fitness),
            ));
        }
        if !(tracking.lost_fitness >= 0.0 && tracking.lost_fitness <= tracking.min_fitness) {
            return Err(invalid(
                "tracking",
                "lost_fitness",
                format!(
                    "{} must lie in [0, min_fitness = {}]",
                    tracking.lost_fitness, tracking.min_fitness
                ),
            ));
        }
        if !(0.0..=1.0).contains(&tracking.min_fitness_share) {
            return Err(invalid(
                "tracking",
                "min_fitness_share",
                format!("{} must lie in [0, 1]", tracking.min_fitness_share),
            ));
        }
        if !(0.0..1.0).contains(&tracking.immigrants) {
            return Err(invalid(
                "tracking",
                "immigrants",
                format!("{} must lie in [0, 1)", tracking.immigrants),
            ));
        }
        let model = raw.model;
        if !(model.step_px.is_finite() && model.step_px >= 0.0) {
            return Err(invalid("model", "step_px", format!("{} must be ≥ 0", model.step_px)));
        }
        if !(model.outer_width_px.is_finite() && model.outer_width_px >= 0.0) {
            return Err(invalid(
                "model",
                "outer_width_px",
                format!("{} must be ≥ 0", model.outer_width_px),
            ));
        }
        if !(model.center_fraction > 0.0 && model.center_fraction <= 1.0) {
            return Err(invalid(
                "model",
                "center_fraction",
                format!("{} must lie in (0, 1]", model.center_fraction),
            ));
        }
        if model.target_points < 16 {
            return Err(invalid("model", "target_points", "must be at least 16".into()));
        }
        let fitness = raw.fitness;
        for (field, v) in [
            ("e1", fitness.e1),
            ("e2", fitness.e2),
            ("e3", fitness.e3),
            ("e4", fitness.e4),
            ("mu", fitness.mu),
        ] {
            if !v.is_finite() {
                return Err(invalid("fitness", field, "must be a finite number".into()));
            }
        }
        if !(fitness.sigma.is_finite() && fitness.sigma > 0.0) {
            return Err(invalid("fitness", "sigma", format!("{} must be > 0", fitness.sigma)));
        }
        if fitness.e1 * 1.0 + fitness.e3 <= 0.0 || fitness.e1 <= 0.0 || fitness.e3 < 0.0 {
            return Err(invalid(
                "fitness",
                "e1",
                "e1 must be > 0 and e3 ≥ 0 (they define the maximum m)".into(),
            ));
        }
        let controller = controller(&raw.controller).map_err(|(field, p)| invalid("controller", field, p))?;
        let detect = detect_settings(raw.detect, dir.unwrap_or(Path::new(BUILT_IN_DIR)))
            .map_err(|(field, p)| invalid("detect", field, p))?;
        if let Some((field, p)) = raw.realtime.problem() {
            return Err(invalid("realtime", field, p));
        }
        Ok(Config {
            calibration,
            calibration_file,
            left_from_hand,
            search,
            ga,
            robust,
            tracking,
            model,
            fitness,
            controller,
            detect,
            realtime: raw.realtime,
        })
    }
}

fn detect_settings(raw: RawDetect, dir: &Path) -> Result<DetectSettings, (&'static str, String)> {
    for (field, v) in [("min_score", raw.min_score), ("iou_threshold", raw.iou_threshold)] {
        if !(v > 0.0 && v <= 1.0) {
            return Err((field, format!("{v} must lie in (0, 1]")));
        }
    }
    if raw.input_size < 32 || raw.input_size % 32 != 0 {
        return Err((
            "input_size",
            format!("{} must be a positive multiple of 32", raw.input_size),
        ));
    }
    Ok(DetectSettings {
        model: dir.join(raw.model),
        onnxruntime: dir.join(raw.onnxruntime),
        min_score: raw.min_score,
        iou_threshold: raw.iou_threshold,
        input_size: raw.input_size,
        threads: raw.threads,
    })
}

fn toml_location(text: &str, span: Option<std::ops::Range<usize>>) -> String {
    match span {
        Some(r) => {
            let line = text[..r.start.min(text.len())].matches('\n').count() + 1;
            format!(" (line {line})")
        }
        None => String::new(),
    }
}

fn check_range(r: [f64; 2], positive: bool) -> Result<(), String> {
    if !r[0].is_finite() || !r[1].is_finite() {
        return Err(format!("[{}, {}] must be finite numbers", r[0], r[1]));
    }
    if r[0] >= r[1] {
        return Err(format!("[{}, {}] is empty or inverted (min must be < max)", r[0], r[1]));
    }
    if positive && r[0] <= 0.0 {
        return Err(format!("[{}, {}] must be positive", r[0], r[1]));
    }
    Ok(())
}

/// A pose from a translation and a `[w, x, y, z]` quaternion that must be of unit length.
fn pose(t: [f64; 3], wxyz: [f64; 4]) -> Result<Isometry3<f64>, String> {
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

/// Validates `[controller]`: the failing field and the problem.
fn controller(raw: &RawController) -> Result<ControllerSettings, (&'static str, String)> {
    for (field, v) in [
        ("rate_hz", raw.rate_hz),
        ("deadline_ms", raw.deadline_ms),
        ("gain", raw.gain),
        ("max_speed_mm_s", raw.max_speed_mm_s),
        ("max_turn_deg_s", raw.max_turn_deg_s),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err((field, format!("{v} must be a positive number")));
        }
    }
    if raw.grasp_position_mm.iter().any(|v| !v.is_finite()) {
        return Err(("grasp_position_mm", "must be finite numbers".into()));
    }
    let hand_from_grasp =
        pose(raw.grasp_position_mm, raw.grasp_rotation_wxyz).map_err(|p| ("grasp_rotation_wxyz", p))?;
    Ok(ControllerSettings {
        rate_hz: raw.rate_hz,
        deadline: std::time::Duration::from_secs_f64(raw.deadline_ms * 1e-3),
        gain: raw.gain,
        max_speed_mm_s: raw.max_speed_mm_s,
        max_turn_rad_s: raw.max_turn_deg_s.to_radians(),
        hand_from_grasp,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fixture(name: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data/config")
            .join(name)
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
        ] {
            let err = Config::load(Some(&fixture(name))).unwrap_err().to_string();
            assert!(err.contains(needle), "{name}: {err}");
            assert!(err.contains(".toml") || err.contains(".conf"), "{name}: {err}");
            assert!(!err.contains('\n'), "{name}: one line: {err}");
        }
    }
}
