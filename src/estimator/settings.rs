//! The estimator's tables — `[search]`, `[ga]`, `[robust]`, `[tracking]`, `[model]` and
//! `[fitness]` — as written (serde, every field defaulted, unknown keys rejected) and
//! validated: [`SearchSpace`] is built from its raw table with `TryFrom`, the others are
//! read as they are and checked by their `validate`.

use serde::Deserialize;

use crate::config::InvalidSetting;
use crate::vision::color::ColorClasses;

/// Which method the estimator runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    /// The paper taken literally: binary GA, raw-hue outer test.
    Paper,
    /// Colour-class aware outer test, coarse-to-fine real-valued GA with local refinement.
    Robust,
}

/// `[search]` as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub(crate) struct RawSearch {
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
    /// Range of the model origin's x in the hand frame, mm.
    pub x_mm: [f64; 2],
    /// Range of its y, mm.
    pub y_mm: [f64; 2],
    /// Range of its z, mm (positive).
    pub z_mm: [f64; 2],
    /// Range of the model length `L`; with the photo's `L_P` it gives the range of α.
    pub size_mm: [f64; 2],
    /// Range of `k = β/α`.
    pub aspect_k: [f64; 2],
}

impl TryFrom<RawSearch> for SearchSpace {
    type Error = InvalidSetting;

    fn try_from(raw: RawSearch) -> Result<Self, InvalidSetting> {
        for (field, range, positive) in [
            ("x_mm", raw.x_mm, false),
            ("y_mm", raw.y_mm, false),
            ("z_mm", raw.z_mm, true),
            ("size_mm", raw.size_mm, true),
            ("aspect_k", raw.aspect_k, true),
        ] {
            check_range(range, positive).map_err(|p| InvalidSetting::new("search", field, p))?;
        }
        Ok(SearchSpace {
            x_mm: raw.x_mm,
            y_mm: raw.y_mm,
            z_mm: raw.z_mm,
            size_mm: raw.size_mm,
            aspect_k: raw.aspect_k,
        })
    }
}

/// A `[min, max]` range: finite, increasing and, when `positive`, above zero.
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

/// `[ga]`: the genetic algorithm.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GaSettings {
    /// The method: the paper's or the robust default.
    pub mode: Mode,
    /// Individuals in the population (at least 4).
    pub population: usize,
    /// Generations of a one-shot estimate.
    pub generations: usize,
    /// Seed of the GA's random numbers.
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
        self.survivors_of(self.population)
    }

    /// How many of a population of `n` (e.g. tracking's) survive each generation at this
    /// survivor share (at least 1, at most all but 1).
    pub fn survivors_of(&self, n: usize) -> usize {
        ((n as f64 * self.survivors).round() as usize).clamp(1, n.saturating_sub(1).max(1))
    }

    /// These settings if the GA can run with them, else the first field that is wrong.
    pub fn validate(self) -> Result<Self, InvalidSetting> {
        let invalid = |field, problem| InvalidSetting::new("ga", field, problem);
        if self.population < 4 {
            return Err(invalid(
                "population",
                format!("{} is too small (at least 4)", self.population),
            ));
        }
        if !(self.survivors > 0.0 && self.survivors < 1.0) {
            return Err(invalid("survivors", format!("{} must lie in (0, 1)", self.survivors)));
        }
        for (field, v) in [
            ("crossover_rate", self.crossover_rate),
            ("bit_mutation_rate", self.bit_mutation_rate),
        ] {
            if !(0.0..=1.0).contains(&v) {
                return Err(invalid(field, format!("{v} must lie in [0, 1]")));
            }
        }
        Ok(self)
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
    /// Weight of the texture terms in the ranking: the left–right correlation of
    /// brightness at the model's points plus their correlation with the photo's
    /// brightness. 0 leaves them out (and makes every result's verdict "not found").
    pub texture_weight: f64,
    /// One-shot searches run again, each from the next seed, while the verdict finds
    /// nothing; the best-scoring result of all is kept (of the fifth retry and later,
    /// only where found or 0.5 higher). 0 searches once.
    pub retries: usize,
}

impl RobustSettings {
    /// These settings if the robust search can run with them, else the first field that
    /// is wrong.
    pub fn validate(self) -> Result<Self, InvalidSetting> {
        let invalid = |field, problem| InvalidSetting::new("robust", field, problem);
        if self.pyramid_levels == 0 || self.pyramid_levels > 5 {
            return Err(invalid(
                "pyramid_levels",
                format!("{} must be 1 to 5", self.pyramid_levels),
            ));
        }
        if self.level_share.len() != self.pyramid_levels
            || self.level_share.iter().any(|v| !v.is_finite() || *v < 0.0)
            || self.level_share.iter().sum::<f64>() <= 0.0
        {
            return Err(invalid(
                "level_share",
                "needs one non-negative share per pyramid level, not all zero".into(),
            ));
        }
        if self.restarts == 0 {
            return Err(invalid("restarts", "must be at least 1".into()));
        }
        if !(0.0..1.0).contains(&self.immigrants) {
            return Err(invalid("immigrants", format!("{} must lie in [0, 1)", self.immigrants)));
        }
        if !(0.0..1.0).contains(&self.min_facing_cos) {
            return Err(invalid(
                "min_facing_cos",
                format!("{} must lie in [0, 1)", self.min_facing_cos),
            ));
        }
        for (field, v) in [
            ("stereo_weight", self.stereo_weight),
            ("texture_weight", self.texture_weight),
        ] {
            if !(v >= 0.0 && v.is_finite()) {
                return Err(invalid(field, format!("{v} must be a non-negative number")));
            }
        }
        Ok(self)
    }
}

impl Default for RobustSettings {
    fn default() -> Self {
        Self {
            pyramid_levels: 3,
            level_share: vec![0.6, 0.3, 0.1],
            restarts: 4,
            prior_samples: 20,
            immigrants: 0.1,
            refine_evaluations: 1500,
            min_facing_cos: 0.3,
            sat_tolerance: 50,
            min_extent_px: 24.0,
            stereo_weight: 0.5,
            texture_weight: 3.0,
            retries: 5,
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
    /// Whether tracking frames (robust mode) read both eyes' brightness and rank by `F`
    /// plus `[robust] texture_weight` × the texture terms, whose verdict also judges the
    /// status: fewer wrong `tracking` poses for about 3 ms more a frame.
    pub texture: bool,
    /// Fitness threads of a tracking frame (0: one per core). A frame's work is small:
    /// waking other threads for each generation can cost more than it saves.
    pub threads: usize,
    /// Gaussian mutation step, in normalised gene units.
    pub sigma: f64,
    /// Below this `F_L + F_R` (`F` without eq. 17's similarity factor) the object
    /// counts as not tracked (status `searching`).
    pub min_fitness: f64,
    /// The floor: a pose whose `F_L + F_R` is below this is published as `lost`, never
    /// `tracking` or `searching` (0 ≤ `lost_fitness` ≤ `min_fitness`).
    pub lost_fitness: f64,
    /// Below this share of the best `F_L + F_R` since the object was acquired it counts
    /// as not tracked either: a model that slipped onto part of its target scores well
    /// above `min_fitness` but far below what the whole target gave.
    pub min_fitness_share: f64,
    /// Share of each generation replaced by view-prior immigrants while searching.
    pub immigrants: f64,
    /// Frames of searching before the object is `lost` and acquired afresh.
    pub lost_after_frames: usize,
    /// Generations of the one-shot robust search that (re)acquires the object.
    pub acquire_generations: usize,
    /// How far beyond the `[search]` space an acquired object is followed and recovered,
    /// as a share of the space's size along each axis on either side (0: not beyond).
    /// The search space is where an object is looked for; a tracked one may come nearer
    /// the hand than it (an approach to grasp) or leave it sideways.
    pub reach: f64,
    /// Tracking frames keep the object's size within this share of the size held since
    /// it was found (0: free): a rigid object does not change size, and a model free to
    /// shrink slid onto the part an occluder left visible and followed the occluder.
    pub size_hold: f64,
}

impl TrackingSettings {
    /// These settings if tracking can run with them, else the first field that is wrong.
    pub fn validate(self) -> Result<Self, InvalidSetting> {
        let invalid = |field, problem| InvalidSetting::new("tracking", field, problem);
        if self.population < 4 {
            return Err(invalid("population", "must be at least 4".into()));
        }
        if !(1..=8).contains(&self.point_stride) {
            return Err(invalid(
                "point_stride",
                format!("{} must lie in 1..=8", self.point_stride),
            ));
        }
        if self.generations_per_frame == 0 || self.acquire_generations == 0 {
            return Err(invalid(
                "generations_per_frame",
                "generations_per_frame and acquire_generations must be at least 1".into(),
            ));
        }
        if !(self.sigma.is_finite() && self.sigma > 0.0) {
            return Err(invalid("sigma", format!("{} must be > 0", self.sigma)));
        }
        if !(self.min_fitness.is_finite() && self.min_fitness >= 0.0) {
            return Err(invalid(
                "min_fitness",
                format!("{} must be a non-negative number", self.min_fitness),
            ));
        }
        if !(self.lost_fitness >= 0.0 && self.lost_fitness <= self.min_fitness) {
            return Err(invalid(
                "lost_fitness",
                format!(
                    "{} must lie in [0, min_fitness = {}]",
                    self.lost_fitness, self.min_fitness
                ),
            ));
        }
        if !(0.0..=1.0).contains(&self.min_fitness_share) {
            return Err(invalid(
                "min_fitness_share",
                format!("{} must lie in [0, 1]", self.min_fitness_share),
            ));
        }
        if !(0.0..1.0).contains(&self.immigrants) {
            return Err(invalid("immigrants", format!("{} must lie in [0, 1)", self.immigrants)));
        }
        if !(0.0..=MAX_REACH).contains(&self.reach) {
            return Err(invalid("reach", format!("{} must lie in [0, {MAX_REACH}]", self.reach)));
        }
        if !(0.0..=1.0).contains(&self.size_hold) {
            return Err(invalid("size_hold", format!("{} must lie in [0, 1]", self.size_hold)));
        }
        Ok(self)
    }
}

impl Default for TrackingSettings {
    fn default() -> Self {
        Self {
            population: 40,
            generations_per_frame: 6,
            point_stride: 2,
            texture: true,
            threads: 1,
            sigma: 0.003,
            min_fitness: 1.0,
            lost_fitness: 0.5,
            min_fitness_share: 0.85,
            immigrants: 0.2,
            lost_after_frames: 30,
            acquire_generations: 300,
            reach: 1.0,
            size_hold: 0.05,
        }
    }
}

/// The largest `[tracking] reach`: beyond it the tracked space would be mostly out of
/// the cameras' view.
const MAX_REACH: f64 = 2.0;

/// `[model]`: how `photopose model` samples the photo.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ModelSettings {
    /// Grid step in photo pixels; 0 chooses it so the box holds about `target_points`.
    pub step_px: f64,
    /// Sampling points wanted inside the box when `step_px` is 0 (at least 16).
    pub target_points: usize,
    /// Width of the outer strip in photo pixels; 0 = 15 % of the box's shorter side.
    pub outer_width_px: f64,
    /// Size of the central rectangle (paper's BECG) whose mean hue is `H̄_in`, as a
    /// fraction of the box.
    pub center_fraction: f64,
}

impl ModelSettings {
    /// These settings if a photo can be sampled with them, else the first field that is
    /// wrong.
    pub fn validate(self) -> Result<Self, InvalidSetting> {
        let invalid = |field, problem| InvalidSetting::new("model", field, problem);
        if !(self.step_px.is_finite() && self.step_px >= 0.0) {
            return Err(invalid("step_px", format!("{} must be ≥ 0", self.step_px)));
        }
        if !(self.outer_width_px.is_finite() && self.outer_width_px >= 0.0) {
            return Err(invalid(
                "outer_width_px",
                format!("{} must be ≥ 0", self.outer_width_px),
            ));
        }
        if !(self.center_fraction > 0.0 && self.center_fraction <= 1.0) {
            return Err(invalid(
                "center_fraction",
                format!("{} must lie in (0, 1]", self.center_fraction),
            ));
        }
        if self.target_points < 16 {
            return Err(invalid("target_points", "must be at least 16".into()));
        }
        Ok(self)
    }
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
    /// Inner point whose colour is close to the stored one (eq. 13).
    pub e1: f64,
    /// Inner point whose colour is not close.
    pub e2: f64,
    /// Outer point that differs from `H̄_in`: background (eq. 16).
    pub e3: f64,
    /// Outer point that looks like the target.
    pub e4: f64,
    /// Outer point: `|H_I − H̄_in| ≥ outer_hue_threshold` is background (eq. 16).
    pub outer_hue_threshold: u8,
    /// Inner point of an "other" colour: close when the hues differ by at most this.
    pub inner_hue_tolerance: u8,
    /// Expected ratio `F_L/F_R` of the similarity factor `g` (eq. 17).
    pub mu: f64,
    /// Width of `g` around `mu` (eq. 17).
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

    /// These constants if the fitness is defined with them, else the first field that is
    /// wrong.
    pub fn validate(self) -> Result<Self, InvalidSetting> {
        let invalid = |field, problem| InvalidSetting::new("fitness", field, problem);
        for (field, v) in [
            ("e1", self.e1),
            ("e2", self.e2),
            ("e3", self.e3),
            ("e4", self.e4),
            ("mu", self.mu),
        ] {
            if !v.is_finite() {
                return Err(invalid(field, "must be a finite number".into()));
            }
        }
        if !(self.sigma.is_finite() && self.sigma > 0.0) {
            return Err(invalid("sigma", format!("{} must be > 0", self.sigma)));
        }
        if self.e1 * 1.0 + self.e3 <= 0.0 || self.e1 <= 0.0 || self.e3 < 0.0 {
            return Err(invalid(
                "e1",
                "e1 must be > 0 and e3 ≥ 0 (they define the maximum m)".into(),
            ));
        }
        Ok(self)
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid() {
        assert!(SearchSpace::try_from(RawSearch::default()).is_ok());
        assert_eq!(GaSettings::default().validate(), Ok(GaSettings::default()));
        assert_eq!(RobustSettings::default().validate(), Ok(RobustSettings::default()));
        assert_eq!(TrackingSettings::default().validate(), Ok(TrackingSettings::default()));
        assert_eq!(ModelSettings::default().validate(), Ok(ModelSettings::default()));
        assert_eq!(FitnessParams::default().validate(), Ok(FitnessParams::default()));
    }

    #[test]
    fn problems_name_table_and_field() {
        let raw = RawSearch {
            size_mm: [0.0, 10.0],
            ..RawSearch::default()
        };
        let e = SearchSpace::try_from(raw).unwrap_err().to_string();
        assert_eq!(e, "[search] size_mm: [0, 10] must be positive");
        let tracking = TrackingSettings {
            reach: 2.5,
            ..TrackingSettings::default()
        };
        assert_eq!(
            tracking.validate().unwrap_err().to_string(),
            "[tracking] reach: 2.5 must lie in [0, 2]"
        );
        let tracking = TrackingSettings {
            size_hold: 1.5,
            ..TrackingSettings::default()
        };
        assert_eq!(
            tracking.validate().unwrap_err().to_string(),
            "[tracking] size_hold: 1.5 must lie in [0, 1]"
        );
        let ga = GaSettings {
            survivors: 1.0,
            ..GaSettings::default()
        };
        assert_eq!(
            ga.validate().unwrap_err().to_string(),
            "[ga] survivors: 1 must lie in (0, 1)"
        );
        let tracking = TrackingSettings {
            acquire_generations: 0,
            ..TrackingSettings::default()
        };
        assert_eq!(
            tracking.validate().unwrap_err().to_string(),
            "[tracking] generations_per_frame: generations_per_frame and acquire_generations must be at least 1"
        );
        let fitness = FitnessParams {
            e3: -0.5,
            ..FitnessParams::default()
        };
        assert_eq!(
            fitness.validate().unwrap_err().to_string(),
            "[fitness] e1: e1 must be > 0 and e3 ≥ 0 (they define the maximum m)"
        );
    }
}
