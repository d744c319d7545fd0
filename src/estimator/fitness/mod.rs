//! The stereo matching fitness of eqs. 12–18: project the model's sampling points into
//! both images, score inner points by colour closeness (Table 1) and outer points by
//! their hue against `H̄_in`, and combine left and right with the similarity factor g.
//!
//! A point costs a few dozen vectorised `f32` operations (pose, pinhole, distortion) and
//! one read of a [`LookupImage`]; scores are counted, not summed per point. The hot
//! loop lives in `kernel`.

use nalgebra::{Isometry3, Matrix3, Point2};

use crate::camera::{Intrinsics, StereoRig};
use crate::estimator::settings::FitnessParams;
use crate::vision::color::is_chromatic;
use crate::vision::frame::FrameLevel;
use crate::vision::lookup::{LevelLookup, LookupImage, SecondByte, TexelRule};

mod kernel;
use crate::estimator::model::PhotoModel;
use crate::estimator::pose::PoseSize;
use kernel::Projection;

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
    /// `F` (eq. 18): the mean of `F_L` and `F_R` times `1 + g`; 2 for a perfect match.
    pub f: f64,
    /// `F_L` (eq. 12), the left image's score: 1 for a perfect match.
    pub left: f64,
    /// `F_R`, the right image's score: 1 for a perfect match.
    pub right: f64,
    /// What the search ranks by: `F`, plus in robust mode the weighted share of inner
    /// points on which the two views agree.
    pub score: f64,
}

impl Fitness {
    /// `F_L + F_R`: `F` without eq. 17's similarity factor, on the same scale (2 for a
    /// perfect match). The tracker judges its status on it.
    pub fn sum(&self) -> f64 {
        self.left + self.right
    }
}

/// The share of a model's inner points that must land on the image for the part off
/// it to cost nothing (robust mode, see [`view_weight`]).
pub const FULL_VIEW: f64 = 0.75;

/// How much a score read on the `share` of a model's points that land on the image
/// counts: fully from [`FULL_VIEW`] up, less in proportion below. A card cut by the
/// image's border is judged on its visible part; a model mostly off the image, where
/// a few points could match by chance, is not.
pub fn view_weight(share: f64) -> f64 {
    (share / FULL_VIEW).clamp(0.0, 1.0)
}

/// Texels inside the image's edge within which the corners of a model's reach must
/// land for all its points to count as on the image without counting them.
const VIEW_MARGIN_PX: f32 = 3.0;

/// Every point of `points` counted as on both images.
fn all_seen(points: &PointSet, counts: &mut kernel::Counts) {
    counts.inner_seen = [points.inner_x.len() as u32; 2];
    counts.outer_seen = [points.outer_x.len() as u32; 2];
}

/// How far `model`'s points reach from its box centre along x and y, photo pixels.
fn reach(model: &PhotoModel) -> [f32; 2] {
    let xy = model
        .inner
        .iter()
        .map(|p| [p.x, p.y])
        .chain(model.outer.iter().copied());
    let [x, y] = xy.fold([0.0f64; 2], |[mx, my], [x, y]| [mx.max(x.abs()), my.max(y.abs())]);
    [x as f32, y as f32]
}

/// Left–right colour agreement tolerances (tighter than the model match: both views
/// see the same surface through the same kind of camera).
const STEREO_HUE_TOLERANCE: u8 = 5;
const STEREO_SAT_TOLERANCE: u8 = 25;

/// Sampling points in struct-of-arrays form (photo pixels from the box centre). Inner
/// points of chromatic colour come first, so the kernel runs two branch-free loops.
#[derive(Debug, Clone, Default)]
pub struct PointSet {
    /// Inner points' x, photo pixels right of the box centre.
    pub inner_x: Vec<f32>,
    /// Inner points' y, photo pixels down from the box centre.
    pub inner_y: Vec<f32>,
    /// Inner points' Table 1 colour code: a hue `0..180` or `BLACK`, `GRAY`, `WHITE`.
    pub inner_code: Vec<u8>,
    /// Inner points' HSV saturation, 0–255.
    pub inner_sat: Vec<u8>,
    /// Inner points' HSV value (brightness), 0–255: the photo's texture.
    pub inner_v: Vec<u8>,
    /// The first `chromatic` inner points have a chromatic code.
    pub chromatic: usize,
    /// Outer strip points' x, photo pixels right of the box centre.
    pub outer_x: Vec<f32>,
    /// Outer strip points' y, photo pixels down from the box centre.
    pub outer_y: Vec<f32>,
}

impl PointSet {
    /// All points of a model (`stride` 1), or one point per `stride` × `stride` block of
    /// the grid, at the block's centre with the block's mean colour: the model as a
    /// thumbnail, matching the blurred images of a coarse pyramid level.
    pub fn from_model(model: &PhotoModel, params: &FitnessParams, stride: usize) -> Self {
        let classes = params.classes();
        let inner: Vec<[f64; 2]> = model.inner.iter().map(|p| [p.x, p.y]).collect();
        let mut points: Vec<([f64; 2], u8, u8, u8)> = blocks(&inner, model.step_px, stride)
            .into_iter()
            .map(|(members, xy)| {
                let (h, s, v) = mean_hsv(members.iter().map(|&i| &model.inner[i]));
                (xy, classes.code(h, s, v), s, v)
            })
            .collect();
        points.sort_by_key(|p| !is_chromatic(p.1));
        let mut set = PointSet {
            chromatic: points.iter().filter(|p| is_chromatic(p.1)).count(),
            ..Default::default()
        };
        for ([x, y], code, sat, v) in points {
            set.inner_x.push(x as f32);
            set.inner_y.push(y as f32);
            set.inner_code.push(code);
            set.inner_sat.push(sat);
            set.inner_v.push(v);
        }
        for (_, [x, y]) in blocks(&model.outer, model.step_px, stride) {
            set.outer_x.push(x as f32);
            set.outer_y.push(y as f32);
        }
        set
    }

    /// Every `k`-th point of each kind (chromatic, achromatic, outer): a cheap preview.
    pub fn every(&self, k: usize) -> Self {
        let k = k.max(1);
        let pick = |v: &[f32], r: std::ops::Range<usize>| v[r].iter().step_by(k).copied().collect::<Vec<_>>();
        let pick8 = |v: &[u8], r: std::ops::Range<usize>| v[r].iter().step_by(k).copied().collect::<Vec<_>>();
        let (c, n) = (self.chromatic, self.inner_x.len());
        let join = |a: Vec<f32>, b: Vec<f32>| [a, b].concat();
        let join8 = |a: Vec<u8>, b: Vec<u8>| [a, b].concat();
        let chromatic = pick(&self.inner_x, 0..c).len();
        Self {
            inner_x: join(pick(&self.inner_x, 0..c), pick(&self.inner_x, c..n)),
            inner_y: join(pick(&self.inner_y, 0..c), pick(&self.inner_y, c..n)),
            inner_code: join8(pick8(&self.inner_code, 0..c), pick8(&self.inner_code, c..n)),
            inner_sat: join8(pick8(&self.inner_sat, 0..c), pick8(&self.inner_sat, c..n)),
            inner_v: join8(pick8(&self.inner_v, 0..c), pick8(&self.inner_v, c..n)),
            chromatic,
            outer_x: pick(&self.outer_x, 0..self.outer_x.len()),
            outer_y: pick(&self.outer_y, 0..self.outer_y.len()),
        }
    }

    /// Number of points, inner and outer.
    pub fn len(&self) -> usize {
        self.inner_x.len() + self.outer_x.len()
    }

    /// Whether the set has no points at all.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Everything the fitness needs that does not change between candidates.
#[derive(Debug, Clone)]
pub struct Scorer {
    /// The `[fitness]` constants: point scores, hue tolerances, `mu`, `sigma`, Table 1.
    pub params: FitnessParams,
    /// How outer points tell target from background.
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
    /// Weight of the left–right agreement in [`Fitness::score`] (0: rank by `F` alone).
    pub stereo_weight: f64,
    /// Rank by `F_L + F_R` instead of `F`, i.e. without eq. 17's similarity factor `g`
    /// (robust mode). An occluder in front of the card hides different parts of it in
    /// each eye, and `g` punished that more than a model shrunk onto the visible part;
    /// the stereo terms check the depth instead.
    pub rank_by_sum: bool,
    /// Read eq. 17's similarity factor on the inner points alone, with this width instead
    /// of `[fitness] sigma` (the tracker's frames): the outer strip lies on whatever is
    /// behind the card, which each eye sees at another place, the card itself alike.
    /// `None`: the paper's, on all points.
    pub inner_similarity: Option<f64>,
    /// Score each image on the points that land on it, weighted by [`view_weight`]
    /// (robust mode), instead of counting points off the image as mismatches (the
    /// paper). A card cut by the image's border then scores as its visible part does,
    /// and a model shrunk away from the border gains nothing.
    pub partial_view: bool,
    /// Model frame size `L_P`, `B_P` in photo pixels.
    pub box_px: [f64; 2],
    /// How far the model's points (inner and outer) reach from the box centre along x
    /// and y, photo pixels.
    pub reach_px: [f32; 2],
    /// `CL_T_H`: hand coordinates → left-camera coordinates (mm), the hand–eye calibration.
    pub left_from_hand: Isometry3<f64>,
    /// `H̄_in` rounded to the nearest OpenCV hue (image hues are integers).
    pub mean_hue: u8,
    /// The central rectangle's colour code (see [`PhotoModel::center_code`]).
    pub center_code: u8,
    /// Mean saturation of the central rectangle's chromatic points.
    pub center_sat: u8,
}

impl Scorer {
    /// A scorer for `model`; `min_extent_px` and `stereo_weight` start at 0 (off).
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
            stereo_weight: 0.0,
            rank_by_sum: false,
            inner_similarity: None,
            partial_view: false,
            box_px: [model.l_p, model.b_p],
            reach_px: reach(model),
            left_from_hand,
            mean_hue: (model.mean_hue.round() as u32 % 180) as u8,
            center_code: model.center_code(),
            center_sat: model.mean_saturation.clamp(0.0, 255.0).round() as u8,
        }
    }

    /// How this scorer's lookup images turn pixel colours into texels.
    pub fn texel_rule(&self) -> TexelRule {
        TexelRule {
            classes: self.params.classes(),
            second: match self.rule {
                OuterRule::RawHue => SecondByte::RawHue,
                OuterRule::ColorClass => SecondByte::Saturation,
            },
            gains: [1.0; 3],
        }
    }

    /// One pyramid level's lookup images for this scorer (once per frame).
    pub fn lookup(&self, level: &FrameLevel) -> LevelLookup {
        LevelLookup::new(level, &self.texel_rule())
    }

    /// Projections of the candidate into the left and right images, `None` when
    /// the model is seen from behind or too edge-on by either camera, or too small.
    fn placements(&self, level: &LevelLookup, c: &PoseSize) -> Option<[Projection; 2]> {
        let left_from_model = self.left_from_hand * c.hand_from_model();
        let right_from_model = level.rig.right_from_left * left_from_model;
        let left = self.placement(&level.left, &left_from_model, c, &level.rig.left, level.scale)?;
        let right = self.placement(&level.right, &right_from_model, c, &level.rig.right, level.scale)?;
        Some([left, right])
    }

    /// The projection into one camera, or `None` per [`Scorer::placements`].
    fn placement(
        &self,
        image: &LookupImage,
        cam_from_model: &Isometry3<f64>,
        c: &PoseSize,
        cam: &Intrinsics,
        scale: f64,
    ) -> Option<Projection> {
        let r: Matrix3<f64> = cam_from_model.rotation.to_rotation_matrix().into_inner();
        let t = cam_from_model.translation.vector;
        let normal = r.column(2).into_owned();
        // The photo's face looks along −z_M; it faces the camera when t·z_M > 0.
        let facing = t.dot(&normal) / t.norm().max(1e-9);
        let (ax, ay) = (r.column(0) / c.alpha, r.column(1) / c.beta());
        // Approximate image extent of each model side, in full-resolution pixels.
        let px = cam.fx / scale / t.z.max(1e-9);
        let too_small = (ax * self.box_px[0]).norm() * px < self.min_extent_px
            || (ay * self.box_px[1]).norm() * px < self.min_extent_px;
        if facing.is_nan() || facing <= self.min_facing_cos || too_small {
            return None;
        }
        Some(kernel::projection(cam, image.origin, [&ax, &ay, &t]))
    }

    /// `F_L` alone (eq. 12): the left image's score, for scans that fix depth later.
    pub fn evaluate_left(&self, points: &PointSet, level: &LevelLookup, c: &PoseSize) -> f64 {
        let left_from_model = self.left_from_hand * c.hand_from_model();
        let Some(pl) = self.placement(&level.left, &left_from_model, c, &level.rig.left, level.scale) else {
            return 0.0;
        };
        let seen = self.counts_on_image(&[(&level.left, &pl)]);
        let mut counts = kernel::count_left(points, &level.left, &pl, &self.tolerances(), seen);
        if !seen {
            all_seen(points, &mut counts);
        }
        self.image_score(points, &counts, 0)
    }

    /// Eq. 18 for one candidate on one pyramid level, and its search score.
    pub fn evaluate(&self, points: &PointSet, level: &LevelLookup, c: &PoseSize) -> Fitness {
        let Some([pl, pr]) = self.placements(level, c) else {
            return Fitness::default();
        };
        let seen = self.counts_on_image(&[(&level.left, &pl), (&level.right, &pr)]);
        let mut counts = kernel::count(
            points,
            [&level.left, &level.right],
            [&pl, &pr],
            &self.tolerances(),
            seen,
        );
        if !seen {
            all_seen(points, &mut counts);
        }
        let [fl, fr] = [0, 1].map(|eye| self.image_score(points, &counts, eye));
        let g = self.similarity(points, &counts, [fl, fr]);
        let f = (fl + fr) / 2.0 * (1.0 + g);
        let confirmed = self.confirmed_share(points, &counts);
        Fitness {
            f,
            left: fl,
            right: fr,
            score: if self.rank_by_sum { fl + fr } else { f } + self.stereo_weight * confirmed,
        }
    }

    /// Eq. 17's similarity factor `g` of the image scores `[fl, fr]`; with
    /// [`Scorer::inner_similarity`], of the two eyes' scores on the inner points alone,
    /// with its width.
    fn similarity(&self, points: &PointSet, counts: &kernel::Counts, [fl, fr]: [f64; 2]) -> f64 {
        if fl == 0.0 || fr == 0.0 {
            return 0.0;
        }
        let ([a, b], sigma) = match self.inner_similarity {
            None => ([fl, fr], self.params.sigma),
            Some(sigma) => {
                let inner = [0, 1].map(|eye| self.inner_score(points, counts, eye));
                if inner.iter().any(|&s| s <= 0.0) {
                    return 0.0;
                }
                (inner, sigma)
            }
        };
        let d = a / b - self.params.mu;
        (-(d * d) / (2.0 * sigma * sigma)).exp()
    }

    /// Image `eye`'s score on the inner points alone (1: every one close), over those on
    /// the image with [`Scorer::partial_view`].
    fn inner_score(&self, points: &PointSet, counts: &kernel::Counts, eye: usize) -> f64 {
        let pr = &self.params;
        let n = if self.partial_view {
            counts.inner_seen[eye] as f64
        } else {
            points.inner_x.len() as f64
        };
        let close = counts.close[eye] as f64;
        (pr.e1 * close + pr.e2 * (n - close)) / (pr.e1 * n.max(1.0))
    }

    /// Whether the kernel must count the points that land on each of `views` (image
    /// and projection): with [`Scorer::partial_view`], unless the model's reach lands
    /// wholly on every image (then all of them do).
    fn counts_on_image(&self, views: &[(&LookupImage, &Projection)]) -> bool {
        self.partial_view
            && !views
                .iter()
                .all(|(img, p)| kernel::wholly_on(img, p, self.reach_px, VIEW_MARGIN_PX))
    }

    /// The share of inner points both views confirm; with [`Scorer::partial_view`], of
    /// those both images show, times [`view_weight`].
    fn confirmed_share(&self, points: &PointSet, counts: &kernel::Counts) -> f64 {
        let n = points.inner_x.len().max(1) as f64;
        if !self.partial_view {
            return counts.confirmed as f64 / n;
        }
        let seen = counts.inner_seen[0].min(counts.inner_seen[1]) as f64;
        if seen == 0.0 {
            return 0.0;
        }
        view_weight(seen / n) * counts.confirmed as f64 / seen
    }

    fn tolerances(&self) -> kernel::Tolerances {
        kernel::Tolerances {
            hue: self.params.inner_hue_tolerance,
            sat: self.sat_tolerance,
            stereo_hue: STEREO_HUE_TOLERANCE,
            stereo_sat: STEREO_SAT_TOLERANCE,
            outer: kernel::OuterTest {
                raw_hue: self.rule == OuterRule::RawHue,
                mean_hue: self.mean_hue,
                threshold: self.params.outer_hue_threshold,
                center_code: self.center_code,
                center_sat: self.center_sat,
                sat_tolerance: self.sat_tolerance,
            },
        }
    }

    /// `F_L` or `F_R` (eqs. 12–16) from the counts of image `eye` (0 left, 1 right): the
    /// point scores over `M`, the score of a perfect match. With
    /// [`Scorer::partial_view`], over the points on the image only, times
    /// [`view_weight`] of their share.
    fn image_score(&self, points: &PointSet, counts: &kernel::Counts, eye: usize) -> f64 {
        let pr = &self.params;
        let [mut n_inner, mut n_outer] = [&points.inner_x, &points.outer_x].map(|v| v.len() as f64);
        let mut weight = 1.0;
        if self.partial_view {
            let seen = counts.inner_seen[eye] as f64;
            weight = view_weight(seen / n_inner.max(1.0));
            (n_inner, n_outer) = (seen, counts.outer_seen[eye] as f64);
        }
        let m = pr.e1 * n_inner + pr.e3 * n_outer;
        if m <= 0.0 || weight == 0.0 {
            return 0.0;
        }
        let (close, background) = (counts.close[eye] as f64, counts.background[eye] as f64);
        weight * (pr.e1 * close + pr.e2 * (n_inner - close) + pr.e3 * background + pr.e4 * (n_outer - background)) / m
    }

    /// Projected pixel positions of all inner and outer points in the left and right
    /// images (for overlays); `None` for points behind a camera.
    pub fn project_points(&self, points: &PointSet, rig: &StereoRig, c: &PoseSize) -> [ProjectedPoints; 2] {
        let left_from_model = self.left_from_hand * c.hand_from_model();
        let right_from_model = rig.right_from_left * left_from_model;
        let [l, r] = [(left_from_model, &rig.left), (right_from_model, &rig.right)].map(|(iso, cam)| {
            let proj = |x: &[f32], y: &[f32]| -> Vec<Option<Point2<f64>>> {
                x.iter()
                    .zip(y)
                    .map(|(&px, &py)| {
                        let p = iso * nalgebra::Point3::new(px as f64 / c.alpha, py as f64 / c.beta(), 0.0);
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

/// Where model points (photo pixels) land in one camera's image for one candidate, in
/// `f32` like the fitness kernel (pose, pinhole, distortion): for other per-point terms.
pub struct PointProjector(Projection);

impl PointProjector {
    /// The projector of candidate `c` through `cam`, which sees the model at
    /// `cam_from_model`.
    pub fn new(cam: &Intrinsics, cam_from_model: &Isometry3<f64>, c: &PoseSize) -> Self {
        let r: Matrix3<f64> = cam_from_model.rotation.to_rotation_matrix().into_inner();
        let (ax, ay) = (r.column(0) / c.alpha, r.column(1) / c.beta());
        let t = cam_from_model.translation.vector;
        Self(kernel::projection(cam, (0, 0), [&ax, &ay, &t]))
    }

    /// Image pixel of model point `(x, y)`; `(-1, -1)` behind the camera.
    #[inline]
    pub fn pixel(&self, x: f32, y: f32) -> (f32, f32) {
        let (u, v) = kernel::pixel(&self.0, x, y);
        // The kernel's coordinates are those of a lookup image padded by one texel.
        (u - 1.0, v - 1.0)
    }
}

/// Pixel positions of a model's points in one image.
#[derive(Debug, Clone)]
pub struct ProjectedPoints {
    /// Image pixels of the inner points, in [`PointSet`] order; `None` behind the camera.
    pub inner: Vec<Option<Point2<f64>>>,
    /// Image pixels of the outer points, in [`PointSet`] order; `None` behind the camera.
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
fn mean_hsv<'a>(points: impl Iterator<Item = &'a crate::estimator::model::InnerPoint>) -> (u8, u8, u8) {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Intrinsics, StereoRig};
    use crate::estimator::model::{InnerPoint, PixelBox};
    use crate::vision::color::GRAY;
    use crate::vision::frame::{ColorPlane, PixelColor};
    use nalgebra::Vector3;

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
            detection: None,
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

    fn score(s: &Scorer, pts: &PointSet, lv: &FrameLevel, c: &PoseSize) -> Fitness {
        s.evaluate(pts, &s.lookup(lv), c)
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
        let f = score(&scorer(OuterRule::ColorClass), &pts, &lv, &candidate());
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
        let f = score(&scorer(OuterRule::RawHue), &pts, &lv, &candidate());
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
        let f = score(&s, &pts, &lv, &candidate());
        assert!((f.left - (4.0 * -0.5 + 4.0 * 0.5) / 10.0).abs() < 1e-12);
        // Entirely outside the image: every point is a mismatch.
        let far = PoseSize {
            position: Vector3::new(500.0, 0.0, 100.0),
            ..candidate()
        };
        let f = score(&s, &pts, &lv, &far);
        assert!((f.left - (4.0 * -0.5 + 4.0 * -1.9) / 10.0).abs() < 1e-12, "{f:?}");
        // Turned 180° about y: the camera sees the back of the photo.
        let back = PoseSize {
            eps: Vector3::new(0.0, 1.0, 0.0),
            ..candidate()
        };
        assert_eq!(score(&s, &pts, &lv, &back), Fitness::default());
    }

    #[test]
    fn partial_view_scores_the_part_on_the_image() {
        // A red patch at the image's right border; the model's right column and its right
        // outer point fall off the image.
        let lv = level(|x, y| if x >= 17 && (8..=11).contains(&y) { 0 } else { GRAY });
        let pts = PointSet::from_model(&model(), &FitnessParams::default(), 1);
        let cut = PoseSize {
            position: Vector3::new(9.5, 0.0, 100.0),
            ..candidate()
        };
        let mut s = scorer(OuterRule::ColorClass);
        let literal = score(&s, &pts, &lv, &cut);
        // Off the image: 2 inner mismatches (−0.5) and 1 outer "target" (−1.9).
        let expected = (2.0 * 2.0 - 2.0 * 0.5 + 3.0 * 0.5 - 1.9) / 10.0;
        assert!((literal.left - expected).abs() < 1e-12, "{literal:?}");
        s.partial_view = true;
        let partial = score(&s, &pts, &lv, &cut);
        // The 2 inner and 3 outer points on the image match perfectly; half the inner
        // points are seen, so the score counts 0.5 / FULL_VIEW of it.
        assert!((partial.left - 0.5 / FULL_VIEW).abs() < 1e-12, "{partial:?}");
        assert_eq!(partial.left, partial.right);
        // A model wholly on the image scores as before.
        let whole = level(|x, y| {
            if (8..=11).contains(&x) && (8..=11).contains(&y) {
                0
            } else {
                GRAY
            }
        });
        assert_eq!(score(&s, &pts, &whole, &candidate()).left, 1.0);
        // Wholly off it: nothing.
        let far = PoseSize {
            position: Vector3::new(500.0, 0.0, 100.0),
            ..candidate()
        };
        assert_eq!(score(&s, &pts, &lv, &far).left, 0.0);
    }

    #[test]
    fn view_weight_is_full_from_three_quarters_in_view() {
        assert_eq!(view_weight(1.0), 1.0);
        assert_eq!(view_weight(FULL_VIEW), 1.0);
        assert!((view_weight(0.5) - 0.5 / FULL_VIEW).abs() < 1e-12);
        assert_eq!(view_weight(0.0), 0.0);
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
        let f = score(&scorer(OuterRule::ColorClass), &pts, &lv, &candidate());
        // F_L = 1, F_R = 0 → g = 0, F = 0.5.
        assert_eq!(f.right, 0.0);
        assert!((f.f - 0.5).abs() < 1e-12);
    }

    #[test]
    fn the_inner_similarity_reads_the_card_not_what_lies_behind_its_strip() {
        // The right eye sees the card's red around it too (a wall of its colour behind
        // the strip, seen elsewhere by the left eye): its outer points look like the
        // target, the inner ones match as in the left eye.
        let mut lv = level(|x, y| {
            if (8..=11).contains(&x) && (8..=11).contains(&y) {
                0
            } else {
                GRAY
            }
        });
        lv.right.px.iter_mut().for_each(|c| c.code = 0);
        let pts = PointSet::from_model(&model(), &FitnessParams::default(), 1);
        let mut s = scorer(OuterRule::ColorClass);
        let paper = score(&s, &pts, &lv, &candidate());
        // F_L = 1, F_R = (4·2 − 4·1.9) / 10 = 0.04: g ≈ 0, F ≈ 0.52.
        assert!((paper.right - 0.04).abs() < 1e-12, "{paper:?}");
        assert!((paper.f - 0.52).abs() < 1e-9, "{paper:?}");
        s.inner_similarity = Some(0.2);
        let inner = score(&s, &pts, &lv, &candidate());
        // The inner points agree: g = 1, F = F_L + F_R.
        assert!((inner.f - 1.04).abs() < 1e-12, "{inner:?}");
        assert_eq!(inner.sum(), paper.sum());
        // Where the card itself differs (the right eye sees no red), g falls again.
        lv.right.px.iter_mut().for_each(|c| c.code = 120);
        assert!(score(&s, &pts, &lv, &candidate()).f < 0.6);
    }
}
