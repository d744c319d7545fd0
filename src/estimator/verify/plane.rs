//! The card's plane from the two eyes' brightness. A card tilted about an axis across
//! the baseline looks the same in the left image at a slightly different tilt and size
//! (the ridge of the colour fitness: 2–3° and 5 % apart at 45° for a 90 px card), and
//! the texture terms on thinned points barely change along it. Here the left image of
//! the pose is held and its plane turned and moved along the line of sight until the
//! right eye sees the same brightness at the same card points (a plane sweep on every
//! model point); the size follows from the plane.

use nalgebra::{Isometry3, Rotation3, UnitQuaternion, Vector3};

use super::texture::{both_eyes, Brightness, Ncc};
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
        both_eyes(
            self.points,
            self.rig,
            self.eyes,
            self.left_from_hand,
            c,
            |inside, _, a, b| {
                if inside {
                    ncc.add(a.0, b.0);
                }
            },
        );
        ncc.value()
    }
}

/// First steps of the sweep: depth 1 %, tilt 2°; each round halves them.
const FIRST_STEP: [f64; 3] = [0.01, 0.035, 0.035];
/// Where the sweep starts: the pose's own depth and plane.
const START: [f64; 3] = [1.0, 0.0, 0.0];
/// Rounds of the sweep.
const ROUNDS: usize = 7;
/// How far the sweep may go from the pose it starts at: depth ±10 %, tilt ±10°. The
/// ridge of a right pose is a few degrees long; a wrong pose is not the sweep's to move.
const REACH: [f64; 3] = [0.1, 0.175, 0.175];

/// `c` moved along the left eye's ridge ([`replaced`]) to where the two eyes agree best
/// ([`TwoEyes::agreement`]): per round, each of depth and the two tilts is tried a step either
/// way and set to the peak of the parabola through the three (within a step).
pub fn settle(two: &TwoEyes, c: &PoseSize, box_px: [f64; 2]) -> PoseSize {
    let at = |p: &[f64; 3]| replaced(c, two.left_from_hand, box_px, p[0], [p[1], p[2]]);
    let score = |p: &[f64; 3]| two.agreement(&at(p));
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
    at(&p)
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
}
