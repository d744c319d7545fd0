//! The card's plane from the two eyes' brightness. A card tilted about an axis across
//! the baseline looks the same in the left image at a slightly different tilt and size
//! (the ridge of the colour fitness: 2–3° and 5 % apart at 45° for a 90 px card), and
//! the texture terms on thinned points barely change along it. Here the left image of
//! the pose is held and its plane turned and moved along the line of sight until the
//! right eye sees the same brightness at the same card points (a plane sweep on every
//! model point); the size follows from the plane.

use nalgebra::{Isometry3, Rotation3, UnitQuaternion, Vector3};

use super::texture::{both_eyes, Brightness, Ncc, Sample};
use crate::camera::StereoRig;
use crate::estimator::fitness::PointSet;
use crate::estimator::pose::PoseSize;

/// A plane for pose `c` that keeps `c`'s image in the left eye: the plane through its
/// centre's line of sight at `depth` times its distance, its normal turned by `tilt`
/// (radians, about the left camera's x and y axes); the model's corners are where the
/// left eye's rays through the old ones meet it (`box_px`: the photo box, for sizes).
pub fn replaced(
    c: &PoseSize,
    left_from_hand: &Isometry3<f64>,
    box_px: [f64; 2],
    depth: f64,
    tilt: [f64; 2],
) -> PoseSize {
    let left = left_from_hand * c.hand_from_model();
    let (r, t) = (left.rotation, left.translation.vector);
    let [l, b] = c.size_mm(box_px[0], box_px[1]);
    let (ex, ey) = (r * Vector3::x() * (l / 2.0), r * Vector3::y() * (b / 2.0));
    let n = UnitQuaternion::from_scaled_axis(Vector3::new(tilt[0], tilt[1], 0.0)) * (r * Vector3::z());
    let on_plane = t * depth;
    let meet = |p: Vector3<f64>| p * (n.dot(&on_plane) / n.dot(&p));
    // The corners (−−, +−, ++, −+) where the rays through the old ones meet the plane:
    // under perspective a quadrilateral, not quite a rectangle; the rectangle taken is
    // its mean: centre, side along x and side along y.
    let [a, b, c, d] = [t - ex - ey, t + ex - ey, t + ex + ey, t - ex + ey].map(meet);
    let along = (b - a + c - d) / 2.0;
    let new_l = along.norm();
    let x = along / new_l;
    let y = n.cross(&x);
    let new_b = ((d - a + c - b) / 2.0).dot(&y).abs();
    let centre = (a + b + c + d) / 4.0;
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_basis_unchecked(&[x, y, n]));
    let hand = left_from_hand.inverse() * Isometry3::from_parts(centre.into(), rotation);
    PoseSize::from_pose(&hand, [new_l, new_b], box_px[0], box_px[1])
}

/// What the sweep reads: the model's points, the rig, both eyes' brightness and the
/// hand–eye transform.
#[derive(Clone, Copy)]
pub struct TwoEyes<'a> {
    /// The model's points (all inner points are read).
    pub points: &'a PointSet,
    /// The cameras.
    pub rig: &'a StereoRig,
    /// Left and right brightness.
    pub eyes: [&'a Brightness; 2],
    /// The hand–eye transform: left camera from hand.
    pub left_from_hand: &'a Isometry3<f64>,
}

impl TwoEyes<'_> {
    /// How alike the two eyes' brightness is at the model's inner points (at least the
    /// texture terms' margin inside its edge) for candidate `c`: a normalised correlation.
    pub fn agreement(&self, c: &PoseSize) -> f64 {
        let mut ncc = Ncc::default();
        self.inside(c, BRIGHTNESS, |a, b| ncc.add(a, b));
        ncc.value()
    }

    /// [`Self::agreement`] without the points where the two eyes disagree far more than
    /// on most (`OUTLIER` times the median gap between their standardised
    /// brightness): where a bar in front of the card shows each eye a different surface.
    /// Those disagree at any plane, and would draw the sweep towards the bar's depth.
    pub fn trimmed_agreement(&self, c: &PoseSize) -> f64 {
        self.trimmed(c, BRIGHTNESS)
    }

    /// [`Self::trimmed_agreement`] on the detail (the stereo term's reading, without its
    /// noise correction) instead of the brightness: where something in front of the card
    /// shows each eye another surface, or its edge at another place.
    pub fn trimmed_detail_agreement(&self, c: &PoseSize) -> f64 {
        self.trimmed(c, DETAIL)
    }

    /// The correlation of the two eyes' `pick` of their samples ([`trimmed_ncc`]).
    fn trimmed(&self, c: &PoseSize, pick: fn(Sample) -> f32) -> f64 {
        let mut pairs = Vec::with_capacity(self.points.inner_x.len());
        self.inside(c, pick, |a, b| pairs.push((a, b)));
        trimmed_ncc(&pairs)
    }

    /// The two eyes' `pick` of their samples at the model's inner points at least the
    /// texture terms' margin inside its edge, for candidate `c`: `visit(left, right)`.
    fn inside(&self, c: &PoseSize, pick: fn(Sample) -> f32, mut visit: impl FnMut(f32, f32)) {
        both_eyes(
            self.points,
            self.rig,
            self.eyes,
            self.left_from_hand,
            c,
            |inside, _, a, b| {
                if inside {
                    visit(pick(a), pick(b));
                }
            },
        );
    }
}

/// A sample's brightness, and its detail.
const BRIGHTNESS: fn(Sample) -> f32 = |s| s.0;
const DETAIL: fn(Sample) -> f32 = |s| s.1;

/// How many times the median gap a point's gap may be for [`TwoEyes::trimmed_agreement`].
const OUTLIER: f32 = 3.0;

/// The correlation of the pairs whose standardised values are not far apart ([`OUTLIER`]).
fn trimmed_ncc(pairs: &[(f32, f32)]) -> f64 {
    if pairs.is_empty() {
        return 0.0;
    }
    let n = pairs.len() as f32;
    let standard = |f: fn(&(f32, f32)) -> f32| {
        let mean = pairs.iter().map(f).sum::<f32>() / n;
        let var = pairs.iter().map(|p| (f(p) - mean).powi(2)).sum::<f32>() / n;
        (mean, var.sqrt().max(1e-3))
    };
    let ((ma, sa), (mb, sb)) = (standard(|p| p.0), standard(|p| p.1));
    let gap = |p: &(f32, f32)| ((p.0 - ma) / sa - (p.1 - mb) / sb).abs();
    let mut gaps: Vec<f32> = pairs.iter().map(gap).collect();
    let mid = gaps.len() / 2;
    let median = *gaps.select_nth_unstable_by(mid, f32::total_cmp).1;
    let mut ncc = Ncc::default();
    for p in pairs.iter().filter(|p| gap(p) <= OUTLIER * median) {
        ncc.add(p.0, p.1);
    }
    ncc.value()
}

/// First steps of the sweep: depth 1 %, tilt 2°; each round halves them.
const FIRST_STEP: [f64; 3] = [0.01, 0.035, 0.035];
/// Where the sweep starts: the pose's own depth and plane.
const START: [f64; 3] = [1.0, 0.0, 0.0];
/// Rounds of the sweep.
const ROUNDS: usize = 7;
/// How far one sweep may go from the pose it starts at: depth ±10 %, tilt ±10°. The
/// ridge of a right pose is a few degrees long; a wrong pose is not the sweep's to move.
const REACH: [f64; 3] = [0.1, 0.175, 0.175];

/// The agreement ([`TwoEyes::agreement`]) from which the eyes see one surface over a
/// pose. Clean cards settle at 0.99 or more (the README's JPEG frame: 0.992), noisy
/// ones under a bar over a fifth of the card at 0.92–0.99.
const ONE_SURFACE: f64 = 0.98;

/// Sweeps at most: each starts where the last ended, while they still move the pose.
/// (One sweep moves a tilt by at most two first steps, 4°.)
const SWEEPS: usize = 3;

/// `c` moved along the left eye's ridge ([`replaced`]) to where the two eyes agree best
/// on every point, if they then see one surface (`ONE_SURFACE`). Otherwise noise, or
/// something in front of the card, makes them differ over part of it: `c` is also swept
/// on the agreement without those points ([`TwoEyes::trimmed_agreement`]), and of the
/// two planes the one that scores higher on it is taken. (Trimming alone settles short
/// of a wrong tilt: there the points far from the axis, which show the tilt, differ
/// most and are left out.)
pub fn settle(two: &TwoEyes, c: &PoseSize, box_px: [f64; 2]) -> PoseSize {
    let (every_point, agreement) = sweeps(two, c, box_px, &|p| two.agreement(p));
    if agreement >= ONE_SURFACE {
        return every_point;
    }
    let (trimmed, trimmed_agreement) = sweeps(two, c, box_px, &|p| two.trimmed_agreement(p));
    if trimmed_agreement >= two.trimmed_agreement(&every_point) {
        trimmed
    } else {
        every_point
    }
}

/// [`sweep`]s from `c` on `agreement` while they move it by more than 0.2 mm or 0.1°:
/// the pose and its agreement.
fn sweeps(two: &TwoEyes, c: &PoseSize, box_px: [f64; 2], agreement: &impl Fn(&PoseSize) -> f64) -> (PoseSize, f64) {
    let mut at = (*c, 0.0);
    for _ in 0..SWEEPS {
        let next = sweep(two, &at.0, box_px, agreement);
        let moved =
            (next.0.position - at.0.position).norm() > 0.2 || next.0.rotation().angle_to(&at.0.rotation()) > 0.002;
        at = next;
        if !moved {
            break;
        }
    }
    at
}

/// One sweep from `c`: per round, each of depth and the two tilts is tried a step either
/// way and set to the peak of the parabola through the three (within a step). The pose
/// and its agreement.
fn sweep(two: &TwoEyes, c: &PoseSize, box_px: [f64; 2], agreement: &impl Fn(&PoseSize) -> f64) -> (PoseSize, f64) {
    let at = |p: &[f64; 3]| replaced(c, two.left_from_hand, box_px, p[0], [p[1], p[2]]);
    let score = |p: &[f64; 3]| agreement(&at(p));
    let mut p = START;
    let mut best = score(&p);
    let mut step = FIRST_STEP;
    for _ in 0..ROUNDS {
        for k in 0..3 {
            let moved = |by: f64| {
                let mut q = p;
                q[k] = (q[k] + by).clamp(START[k] - REACH[k], START[k] + REACH[k]);
                q
            };
            let (lo, hi) = (moved(-step[k]), moved(step[k]));
            let (a, b) = (score(&lo), score(&hi));
            let curve = a + b - 2.0 * best;
            let shift = if curve < 0.0 {
                (0.5 * (a - b) / curve).clamp(-1.0, 1.0)
            } else if a > b {
                -1.0
            } else {
                1.0
            };
            let q = moved(shift * step[k]);
            let s = score(&q);
            for (cand, v) in [(lo, a), (hi, b), (q, s)] {
                if v > best {
                    (p, best) = (cand, v);
                }
            }
        }
        step = step.map(|s| s / 2.0);
    }
    (at(&p), best)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tilted_card() -> (PoseSize, Isometry3<f64>) {
        let left_from_hand = Isometry3::new(Vector3::new(30.0, -20.0, 0.0), Vector3::z() * 0.1);
        let left_from_model = Isometry3::new(Vector3::new(40.0, 30.0, 600.0), Vector3::new(0.6, 0.3, 0.2));
        let hand = left_from_hand.inverse() * left_from_model;
        (PoseSize::from_pose(&hand, [120.0, 90.0], 240.0, 180.0), left_from_hand)
    }

    #[test]
    fn the_same_plane_is_the_same_pose_and_a_farther_one_a_larger_card() {
        let (c, left_from_hand) = tilted_card();
        let box_px = [240.0, 180.0];
        let same = replaced(&c, &left_from_hand, box_px, 1.0, [0.0, 0.0]);
        assert!((same.position - c.position).norm() < 1e-9);
        assert!(same.rotation().angle_to(&c.rotation()) < 1e-9);
        assert!((same.alpha - c.alpha).abs() < 1e-9 && (same.k - c.k).abs() < 1e-9);
        // The plane 10 % farther along every line of sight: the card 10 % larger, its
        // orientation unchanged, its centre 10 % farther from the left camera.
        let far = replaced(&c, &left_from_hand, box_px, 1.1, [0.0, 0.0]);
        let [l, b] = far.size_mm(box_px[0], box_px[1]);
        assert!((l - 132.0).abs() < 1e-9 && (b - 99.0).abs() < 1e-9, "{l} {b}");
        assert!(far.rotation().angle_to(&c.rotation()) < 1e-9);
        let centre = |p: &PoseSize| (left_from_hand * p.hand_from_model()).translation.vector;
        assert!((centre(&far) - centre(&c) * 1.1).norm() < 1e-9);
        // A turned plane: the card's normal turned by as much about the camera's axis.
        let turned = replaced(&c, &left_from_hand, box_px, 1.0, [0.05, -0.03]);
        let normal = |p: &PoseSize| (left_from_hand * p.hand_from_model()).rotation * Vector3::z();
        let expected = UnitQuaternion::from_scaled_axis(Vector3::new(0.05, -0.03, 0.0)) * normal(&c);
        assert!((normal(&turned) - expected).norm() < 1e-9);
    }

    /// A texture seen alike by both eyes, except a fifth of the points where the right
    /// eye sees a flat bar: the plain correlation drops, the trimmed one leaves the bar
    /// out. Two unrelated textures are not made to agree by the trimming.
    #[test]
    fn the_trimmed_agreement_leaves_out_a_bar_but_not_a_mismatch() {
        let texture = |i: usize, seed: u64| {
            let x = (i as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ seed.wrapping_mul(0xBF58_476D_1CE4_E5B9);
            let x = (x ^ (x >> 31)).wrapping_mul(0x94D0_49BB_1331_11EB);
            ((x ^ (x >> 29)) % 211) as f32
        };
        let seen: Vec<(f32, f32)> = (0..2000).map(|i| (texture(i, 0), texture(i, 0) + 0.5)).collect();
        let barred: Vec<(f32, f32)> = seen
            .iter()
            .enumerate()
            .map(|(i, &(a, b))| (a, if i % 5 == 0 { 30.0 } else { b }))
            .collect();
        let unrelated: Vec<(f32, f32)> = (0..2000).map(|i| (texture(i, 0), texture(i, 1))).collect();
        let plain = |pairs: &[(f32, f32)]| {
            let mut ncc = Ncc::default();
            pairs.iter().for_each(|p| ncc.add(p.0, p.1));
            ncc.value()
        };
        assert!(trimmed_ncc(&seen) > 0.999);
        assert!(plain(&barred) < 0.85, "{}", plain(&barred));
        assert!(trimmed_ncc(&barred) > 0.98, "{}", trimmed_ncc(&barred));
        assert!(trimmed_ncc(&unrelated).abs() < 0.2, "{}", trimmed_ncc(&unrelated));
    }
}
