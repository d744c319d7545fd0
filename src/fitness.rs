//! The stereo matching fitness of eqs. 12–18: project the model's sampling points into
//! both images, score inner points by colour closeness (Table 1) and outer points by
//! their hue against `H̄_in`, and combine left and right with the similarity factor g.

use nalgebra::{Isometry3, Matrix3, Point2, Vector3};

use crate::camera::Intrinsics;
use crate::color::{hue_distance, is_chromatic};
use crate::config::FitnessParams;
use crate::frame::{ColorPlane, FrameLevel};
use crate::model::PhotoModel;
use crate::pose::PoseSize;

/// How an outer point decides that it sees the target rather than background.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OuterRule {
    /// Paper, eq. 16 on the raw OpenCV hue (grey pixels have hue 0).
    RawHue,
    /// The pixel's Table 1 class: a chromatic pixel within the threshold of `H̄_in`, or the
    /// same achromatic class as the central rectangle, looks like the target.
    ColorClass,
}

/// Fitness of one candidate: `F` (eq. 18) and its per-image parts `F_L`, `F_R`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Fitness {
    pub f: f64,
    pub left: f64,
    pub right: f64,
}

/// Sampling points in struct-of-arrays form (photo pixels from the box centre).
#[derive(Debug, Clone, Default)]
pub struct PointSet {
    pub inner_x: Vec<f64>,
    pub inner_y: Vec<f64>,
    pub inner_code: Vec<u8>,
    pub inner_sat: Vec<u8>,
    pub outer_x: Vec<f64>,
    pub outer_y: Vec<f64>,
}

impl PointSet {
    /// All points of a model (`stride` 1), or one point per `stride` × `stride` block of
    /// the grid, at the block's centre with the block's mean colour: the model as a
    /// thumbnail, matching the blurred images of a coarse pyramid level.
    pub fn from_model(model: &PhotoModel, params: &FitnessParams, stride: usize) -> Self {
        let classes = params.classes();
        let inner: Vec<[f64; 2]> = model.inner.iter().map(|p| [p.x, p.y]).collect();
        let mut set = PointSet::default();
        for (members, [x, y]) in blocks(&inner, model.step_px, stride) {
            let (h, s, v) = mean_hsv(members.iter().map(|&i| &model.inner[i]));
            set.inner_x.push(x);
            set.inner_y.push(y);
            set.inner_code.push(classes.code(h, s, v));
            set.inner_sat.push(s);
        }
        for (_, [x, y]) in blocks(&model.outer, model.step_px, stride) {
            set.outer_x.push(x);
            set.outer_y.push(y);
        }
        set
    }

    pub fn len(&self) -> usize {
        self.inner_x.len() + self.outer_x.len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Everything the fitness needs that does not change between candidates.
#[derive(Debug, Clone)]
pub struct Scorer {
    pub params: FitnessParams,
    pub rule: OuterRule,
    /// A candidate whose card normal makes |cos| below this with either line of sight
    /// scores 0; seen from behind always scores 0.
    pub min_facing_cos: f64,
    /// A chromatic inner point also needs the saturation within this (255: hue only, as
    /// in the paper).
    pub sat_tolerance: u8,
    /// A candidate whose model spans fewer full-resolution pixels than this along either
    /// side (in either image) scores 0: a speck of the right colour is no match.
    pub min_extent_px: f64,
    /// Model frame size `L_P`, `B_P` in photo pixels.
    pub box_px: [f64; 2],
    pub left_from_hand: Isometry3<f64>,
    /// `H̄_in` rounded to the nearest OpenCV hue (image hues are integers), and the
    /// central rectangle's colour code.
    pub mean_hue: u8,
    pub center_code: u8,
    /// Mean saturation of the central rectangle's chromatic points.
    pub center_sat: u8,
}

/// Per-camera transform of one candidate: a model point (mm) maps to `t + x·ax + y·ay`.
struct Placement {
    t: Vector3<f64>,
    ax: Vector3<f64>,
    ay: Vector3<f64>,
}

impl Scorer {
    pub fn new(
        model: &PhotoModel,
        params: FitnessParams,
        rule: OuterRule,
        min_facing_cos: f64,
        sat_tolerance: u8,
        left_from_hand: Isometry3<f64>,
    ) -> Self {
        Self {
            params,
            rule,
            min_facing_cos,
            sat_tolerance,
            min_extent_px: 0.0,
            box_px: [model.l_p, model.b_p],
            left_from_hand,
            mean_hue: (model.mean_hue.round() as u32 % 180) as u8,
            center_code: model.center_code(),
            center_sat: model.mean_saturation.clamp(0.0, 255.0).round() as u8,
        }
    }

    /// Transforms of the candidate into the left and right cameras, `None` when the
    /// model is seen from behind or too edge-on by either camera.
    fn placements(&self, level: &FrameLevel, c: &PoseSize) -> Option<[Placement; 2]> {
        let left_from_model = self.left_from_hand * c.hand_from_model();
        let right_from_model = level.rig.right_from_left * left_from_model;
        let (inv_a, inv_b) = (1.0 / c.alpha, 1.0 / c.beta());
        let mut out = Vec::with_capacity(2);
        for (iso, cam) in [(left_from_model, &level.rig.left), (right_from_model, &level.rig.right)] {
            let r: Matrix3<f64> = iso.rotation.to_rotation_matrix().into_inner();
            let t = iso.translation.vector;
            let normal = r.column(2).into_owned();
            // The photo's face looks along −z_M; it faces the camera when t·z_M > 0.
            let facing = t.dot(&normal) / t.norm().max(1e-9);
            let (ax, ay) = (r.column(0) * inv_a, r.column(1) * inv_b);
            // Approximate image extent of each model side, in full-resolution pixels.
            let px = cam.fx / level.scale / t.z.max(1e-9);
            let too_small = (ax * self.box_px[0]).norm() * px < self.min_extent_px
                || (ay * self.box_px[1]).norm() * px < self.min_extent_px;
            if facing.is_nan() || facing <= self.min_facing_cos || too_small {
                return None;
            }
            out.push(Placement { t, ax, ay });
        }
        let right = out.pop()?;
        let left = out.pop()?;
        Some([left, right])
    }

    /// `F_L` alone (eq. 12): the left image's score, for scans that fix depth later.
    pub fn evaluate_left(&self, points: &PointSet, level: &FrameLevel, c: &PoseSize) -> f64 {
        let Some([pl, _]) = self.placements(level, c) else {
            return 0.0;
        };
        let m = self.params.e1 * points.inner_x.len() as f64 + self.params.e3 * points.outer_x.len() as f64;
        if m <= 0.0 {
            return 0.0;
        }
        self.image_sum(points, &level.left, &level.rig.left, &pl) / m
    }

    /// Eq. 18 for one candidate on one pyramid level.
    pub fn evaluate(&self, points: &PointSet, level: &FrameLevel, c: &PoseSize) -> Fitness {
        let Some([pl, pr]) = self.placements(level, c) else {
            return Fitness::default();
        };
        let m = self.params.e1 * points.inner_x.len() as f64 + self.params.e3 * points.outer_x.len() as f64;
        if m <= 0.0 {
            return Fitness::default();
        }
        let fl = self.image_sum(points, &level.left, &level.rig.left, &pl) / m;
        let fr = self.image_sum(points, &level.right, &level.rig.right, &pr) / m;
        let g = if fl == 0.0 || fr == 0.0 {
            0.0
        } else {
            let d = fl / fr - self.params.mu;
            (-(d * d) / (2.0 * self.params.sigma * self.params.sigma)).exp()
        };
        Fitness {
            f: (fl + fr) / 2.0 * (1.0 + g),
            left: fl,
            right: fr,
        }
    }

    /// Sum of eqs. 15 and 16 over all points in one image.
    fn image_sum(&self, points: &PointSet, plane: &ColorPlane, cam: &Intrinsics, p: &Placement) -> f64 {
        let pr = &self.params;
        let mut sum = 0.0;
        for i in 0..points.inner_x.len() {
            sum += match pixel(plane, cam, p, points.inner_x[i], points.inner_y[i]) {
                Some(idx) if self.inner_close(points.inner_code[i], points.inner_sat[i], plane, idx) => pr.e1,
                _ => pr.e2,
            };
        }
        for i in 0..points.outer_x.len() {
            sum += match pixel(plane, cam, p, points.outer_x[i], points.outer_y[i]) {
                Some(idx) if !self.outer_is_target(plane, idx) => pr.e3,
                _ => pr.e4,
            };
        }
        sum
    }

    /// Figure 8: achromatic stored colours match the same class; chromatic ones match a
    /// chromatic pixel of close hue.
    #[inline]
    fn inner_close(&self, model: u8, model_sat: u8, plane: &ColorPlane, idx: usize) -> bool {
        let image = plane.px[idx].code;
        if is_chromatic(model) {
            is_chromatic(image)
                && hue_distance(model, image) <= self.params.inner_hue_tolerance
                && model_sat.abs_diff(plane.px[idx].sat) <= self.sat_tolerance
        } else {
            model == image
        }
    }

    /// True when an outer point's pixel looks like the target (eq. 16's `e4` case).
    #[inline]
    fn outer_is_target(&self, plane: &ColorPlane, idx: usize) -> bool {
        let threshold = self.params.outer_hue_threshold;
        let mean_hue = self.mean_hue;
        match self.rule {
            OuterRule::RawHue => hue_distance(plane.px[idx].hue, mean_hue) < threshold,
            OuterRule::ColorClass => {
                let code = plane.px[idx].code;
                if is_chromatic(self.center_code) {
                    is_chromatic(code)
                        && hue_distance(code, mean_hue) < threshold
                        && plane.px[idx].sat.abs_diff(self.center_sat) <= self.sat_tolerance
                } else {
                    code == self.center_code
                }
            }
        }
    }

    /// Projected pixel positions of all inner and outer points in the left and right
    /// images (for overlays); `None` for points behind a camera.
    pub fn project_points(&self, points: &PointSet, level: &FrameLevel, c: &PoseSize) -> [ProjectedPoints; 2] {
        let left_from_model = self.left_from_hand * c.hand_from_model();
        let right_from_model = level.rig.right_from_left * left_from_model;
        let [l, r] = [(left_from_model, &level.rig.left), (right_from_model, &level.rig.right)].map(|(iso, cam)| {
            let proj = |x: &[f64], y: &[f64]| -> Vec<Option<Point2<f64>>> {
                x.iter()
                    .zip(y)
                    .map(|(&px, &py)| {
                        let p = iso * nalgebra::Point3::new(px / c.alpha, py / c.beta(), 0.0);
                        cam.project(&p)
                    })
                    .collect()
            };
            ProjectedPoints {
                inner: proj(&points.inner_x, &points.inner_y),
                outer: proj(&points.outer_x, &points.outer_y),
            }
        });
        [l, r]
    }
}

/// Pixel positions of a model's points in one image.
#[derive(Debug, Clone)]
pub struct ProjectedPoints {
    pub inner: Vec<Option<Point2<f64>>>,
    pub outer: Vec<Option<Point2<f64>>>,
}

/// Groups grid points (spacing `step`) into `stride` × `stride` blocks: each block's
/// member indices and mean position, in a deterministic order.
fn blocks(points: &[[f64; 2]], step: f64, stride: usize) -> Vec<(Vec<usize>, [f64; 2])> {
    let stride = stride.max(1) as i64;
    let min = |i: usize| points.iter().map(|p| p[i]).fold(f64::INFINITY, f64::min);
    let (x0, y0) = (min(0), min(1));
    let mut map: std::collections::BTreeMap<(i64, i64), Vec<usize>> = Default::default();
    for (i, p) in points.iter().enumerate() {
        let ix = ((p[0] - x0) / step).round() as i64;
        let iy = ((p[1] - y0) / step).round() as i64;
        map.entry((iy.div_euclid(stride), ix.div_euclid(stride)))
            .or_default()
            .push(i);
    }
    map.into_values()
        .map(|m| {
            let n = m.len() as f64;
            let x = m.iter().map(|&i| points[i][0]).sum::<f64>() / n;
            let y = m.iter().map(|&i| points[i][1]).sum::<f64>() / n;
            (m, [x, y])
        })
        .collect()
}

/// Mean colour of model points: saturation-weighted circular mean hue, mean S and V.
fn mean_hsv<'a>(points: impl Iterator<Item = &'a crate::model::InnerPoint>) -> (u8, u8, u8) {
    let (mut cx, mut cy, mut s, mut v, mut n) = (0.0f64, 0.0f64, 0.0, 0.0, 0.0);
    for p in points {
        let a = p.h as f64 * std::f64::consts::PI / 90.0;
        cx += a.cos() * p.s as f64;
        cy += a.sin() * p.s as f64;
        s += p.s as f64;
        v += p.v as f64;
        n += 1.0;
    }
    let n = f64::max(n, 1.0);
    let deg = cy.atan2(cx).to_degrees().rem_euclid(360.0);
    (
        ((deg / 2.0).round() as u32 % 180) as u8,
        (s / n).round() as u8,
        (v / n).round() as u8,
    )
}

/// The pixel index a model point (photo pixels from the box centre) lands on, or `None`
/// when it falls outside the image or behind the camera.
#[inline(always)]
fn pixel(plane: &ColorPlane, cam: &Intrinsics, p: &Placement, x: f64, y: f64) -> Option<usize> {
    let c = p.t + p.ax * x + p.ay * y;
    if c.z <= 1e-6 {
        return None;
    }
    let (xd, yd) = cam.distort(c.x / c.z, c.y / c.z);
    // Nearest pixel: +0.5 then truncation (valid once the value is known non-negative).
    let u = cam.fx * xd + cam.cx + 0.5;
    let v = cam.fy * yd + cam.cy + 0.5;
    if !(u >= 0.0 && v >= 0.0 && u < plane.width as f64 && v < plane.height as f64) {
        return None;
    }
    Some(v as usize * plane.width + u as usize)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::StereoRig;
    use crate::color::GRAY;
    use crate::frame::PixelColor;
    use crate::model::{InnerPoint, PixelBox};

    /// A 20×20-pixel world: pinhole f = 100, identical left and right cameras
    /// (zero baseline) so both images are the same tiny hand-made picture.
    fn level(code: impl Fn(usize, usize) -> u8) -> FrameLevel {
        let cam = Intrinsics::pinhole(100.0, 100.0, 9.5, 9.5);
        let mut plane = ColorPlane {
            width: 20,
            height: 20,
            px: vec![PixelColor::default(); 400],
        };
        for y in 0..20 {
            for x in 0..20 {
                let c = code(x, y);
                plane.px[y * 20 + x] = PixelColor {
                    code: c,
                    sat: 255,
                    hue: if is_chromatic(c) { c } else { 0 },
                };
            }
        }
        FrameLevel {
            scale: 1.0,
            rig: StereoRig {
                width: 20,
                height: 20,
                left: cam,
                right: cam,
                right_from_left: Isometry3::identity(),
            },
            left: plane.clone(),
            right: plane,
        }
    }

    /// A model of 2×2 inner points (hue 0 red) and 4 outer points, 2 px apart.
    fn model() -> PhotoModel {
        let red = |x, y| InnerPoint {
            x,
            y,
            h: 0,
            s: 255,
            v: 255,
        };
        PhotoModel {
            format: "photopose-model".into(),
            version: 1,
            photo: "t.png".into(),
            bbox: PixelBox { x: 0, y: 0, w: 4, h: 4 },
            l_p: 4.0,
            b_p: 4.0,
            step_px: 2.0,
            outer_width_px: 2.0,
            mean_hue: 0.0,
            mean_saturation: 255.0,
            center_class: "chromatic".into(),
            inner: vec![red(-1.0, -1.0), red(1.0, -1.0), red(-1.0, 1.0), red(1.0, 1.0)],
            outer: vec![[-3.0, 0.0], [3.0, 0.0], [0.0, -3.0], [0.0, 3.0]],
        }
    }

    /// Model at 100 mm with α = 1 px/mm: a model pixel offset of 1 maps to 1 mm, i.e.
    /// 1 image pixel at f = 100.
    fn candidate() -> PoseSize {
        PoseSize {
            position: Vector3::new(0.0, 0.0, 100.0),
            eps: Vector3::zeros(),
            alpha: 1.0,
            k: 1.0,
        }
    }

    fn scorer(rule: OuterRule) -> Scorer {
        Scorer::new(
            &model(),
            FitnessParams::default(),
            rule,
            0.0,
            255,
            Isometry3::identity(),
        )
    }

    #[test]
    fn perfect_match_scores_two() {
        // Red 4×4 patch around the centre pixel (9.5, 9.5) → pixels 8..=11; grey elsewhere.
        let lv = level(|x, y| {
            if (8..=11).contains(&x) && (8..=11).contains(&y) {
                0
            } else {
                GRAY
            }
        });
        let pts = PointSet::from_model(&model(), &FitnessParams::default(), 1);
        let f = scorer(OuterRule::ColorClass).evaluate(&pts, &lv, &candidate());
        // All 4 inner close (4·2) + 4 outer background (4·0.5) → F_L = F_R = 1, g = 1, F = 2.
        assert!((f.left - 1.0).abs() < 1e-12 && (f.right - 1.0).abs() < 1e-12);
        assert!((f.f - 2.0).abs() < 1e-12);
    }

    #[test]
    fn paper_rule_punishes_grey_background_with_hue_zero() {
        let lv = level(|x, y| {
            if (8..=11).contains(&x) && (8..=11).contains(&y) {
                0
            } else {
                GRAY
            }
        });
        let pts = PointSet::from_model(&model(), &FitnessParams::default(), 1);
        let f = scorer(OuterRule::RawHue).evaluate(&pts, &lv, &candidate());
        // Raw hue of grey is 0 = H̄_in: every outer point scores e4 = −1.9.
        let expected = (4.0 * 2.0 - 4.0 * 1.9) / (4.0 * 2.0 + 4.0 * 0.5);
        assert!((f.left - expected).abs() < 1e-12, "{f:?}");
        assert!((f.f - 2.0 * expected).abs() < 1e-12);
    }

    #[test]
    fn mismatches_points_outside_and_back_facing() {
        // All blue: inner points mismatch (−0.5 each), outer points are background.
        let lv = level(|_, _| 120);
        let pts = PointSet::from_model(&model(), &FitnessParams::default(), 1);
        let s = scorer(OuterRule::ColorClass);
        let f = s.evaluate(&pts, &lv, &candidate());
        assert!((f.left - (4.0 * -0.5 + 4.0 * 0.5) / 10.0).abs() < 1e-12);
        // Entirely outside the image: every point is a mismatch.
        let far = PoseSize {
            position: Vector3::new(500.0, 0.0, 100.0),
            ..candidate()
        };
        let f = s.evaluate(&pts, &lv, &far);
        assert!((f.left - (4.0 * -0.5 + 4.0 * -1.9) / 10.0).abs() < 1e-12, "{f:?}");
        // Turned 180° about y: the camera sees the back of the photo.
        let back = PoseSize {
            eps: Vector3::new(0.0, 1.0, 0.0),
            ..candidate()
        };
        assert_eq!(s.evaluate(&pts, &lv, &back), Fitness::default());
    }

    #[test]
    fn similarity_factor_halves_unbalanced_images() {
        let mut lv = level(|x, y| {
            if (8..=11).contains(&x) && (8..=11).contains(&y) {
                0
            } else {
                GRAY
            }
        });
        lv.right.px.iter_mut().for_each(|c| c.code = 120);
        let pts = PointSet::from_model(&model(), &FitnessParams::default(), 1);
        let f = scorer(OuterRule::ColorClass).evaluate(&pts, &lv, &candidate());
        // F_L = 1, F_R = 0 → g = 0, F = 0.5.
        assert_eq!(f.right, 0.0);
        assert!((f.f - 0.5).abs() < 1e-12);
    }
}
