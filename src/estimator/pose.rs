//! A candidate solution Φ = (x, y, z, ε1, ε2, ε3, α, k) of the paper's eq. 11: the
//! model's pose in the hand frame and its pixel-to-millimetre ratios.

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};

use crate::camera::geometry::w_nonnegative;

/// Pose and size of a photo-model in the hand frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseSize {
    /// Model origin in the hand frame, mm.
    pub position: Vector3<f64>,
    /// Vector part (ε1, ε2, ε3) of the unit quaternion, scalar part `η = sqrt(1 − |ε|²)`.
    pub eps: Vector3<f64>,
    /// PM ratio along model x, pixels per mm.
    pub alpha: f64,
    /// Ratio factor, `β = α·k`.
    pub k: f64,
}

impl PoseSize {
    /// `β = α·k`, pixels per mm along model y.
    pub fn beta(&self) -> f64 {
        self.alpha * self.k
    }

    /// The rotation `H_R_M`; an `|ε| > 1` is projected onto the unit sphere (η = 0).
    pub fn rotation(&self) -> UnitQuaternion<f64> {
        let n2 = self.eps.norm_squared();
        let (eps, eta) = if n2 > 1.0 {
            (self.eps / n2.sqrt(), 0.0)
        } else {
            (self.eps, (1.0 - n2).sqrt())
        };
        UnitQuaternion::from_quaternion(Quaternion::new(eta, eps.x, eps.y, eps.z))
    }

    /// `H_T_M`: model coordinates → hand coordinates.
    pub fn hand_from_model(&self) -> Isometry3<f64> {
        Isometry3::from_parts(Translation3::from(self.position), self.rotation())
    }

    /// Model size `[L, B]` in mm for a photo box of `l_p × b_p` pixels (eq. 5).
    pub fn size_mm(&self, l_p: f64, b_p: f64) -> [f64; 2] {
        [l_p / self.alpha, b_p / self.beta()]
    }

    /// The candidate that places a `size_mm` model at `hand_from_model`.
    pub fn from_pose(hand_from_model: &Isometry3<f64>, size_mm: [f64; 2], l_p: f64, b_p: f64) -> Self {
        let [_, x, y, z] = wxyz(&hand_from_model.rotation);
        let alpha = l_p / size_mm[0];
        let beta = b_p / size_mm[1];
        Self {
            position: hand_from_model.translation.vector,
            eps: Vector3::new(x, y, z),
            alpha,
            k: beta / alpha,
        }
    }

    /// This pose turned by `tilt` (radians) about the left-camera axis `axis` through
    /// its centre (`left_from_hand` the hand–eye transform), and stretched across the
    /// axis by `1 / cos tilt` so that its image keeps the extent it had.
    pub fn tilted(&self, left_from_hand: &Isometry3<f64>, axis: Vector3<f64>, tilt: f64) -> Self {
        let left = left_from_hand * self.hand_from_model();
        let (mx, my) = (left.rotation * Vector3::x(), left.rotation * Vector3::y());
        let across = Vector3::z().cross(&axis);
        let stretch = 1.0 / tilt.cos().abs().max(0.2) - 1.0;
        let turn = UnitQuaternion::from_scaled_axis(axis * tilt);
        let hand = left_from_hand.inverse() * Isometry3::from_parts(left.translation, turn * left.rotation);
        let (fl, fb) = (
            1.0 + stretch * mx.dot(&across).powi(2),
            1.0 + stretch * my.dot(&across).powi(2),
        );
        let mut q = Self::from_pose(&hand, [1.0, 1.0], 1.0, 1.0);
        q.alpha = self.alpha / fl;
        q.k = self.k * fl / fb;
        q
    }

    /// This pose rolled by `angle` (radians) about the left camera's line of sight
    /// through its centre (`left_from_hand` the hand–eye transform), size unchanged.
    pub fn rolled(&self, left_from_hand: &Isometry3<f64>, angle: f64) -> Self {
        let left = left_from_hand * self.hand_from_model();
        let sight = left.translation.vector.normalize();
        let turned = UnitQuaternion::from_scaled_axis(sight * angle) * left.rotation;
        let hand = left_from_hand.inverse() * Isometry3::from_parts(left.translation, turned);
        Self {
            alpha: self.alpha,
            k: self.k,
            ..Self::from_pose(&hand, [1.0, 1.0], 1.0, 1.0)
        }
    }

    /// The model turned half round about its own normal: the same place, plane and
    /// size, upside down.
    pub fn half_turned(&self) -> Self {
        let turned = self.hand_from_model() * Isometry3::rotation(Vector3::z() * std::f64::consts::PI);
        Self {
            alpha: self.alpha,
            k: self.k,
            ..Self::from_pose(&turned, [1.0, 1.0], 1.0, 1.0)
        }
    }

    /// The left camera's line of sight to this pose's centre, in the hand frame
    /// (`left_from_hand` the hand–eye transform); its length is the centre's distance.
    pub fn sight(&self, left_from_hand: &Isometry3<f64>) -> Vector3<f64> {
        left_from_hand.inverse_transform_vector(&(left_from_hand * self.hand_from_model()).translation.vector)
    }

    /// Its one-sided and central resizes ([`PoseSize::resized`]) for a `box_px` photo
    /// box: the length, then the width, each times every one of `factors`, about either
    /// edge and the centre.
    pub fn resizes(&self, box_px: [f64; 2], factors: &[f64]) -> Vec<Self> {
        let mut out = Vec::with_capacity(6 * factors.len());
        for along_length in [true, false] {
            for &factor in factors {
                for side in [-0.5, 0.0, 0.5] {
                    out.push(self.resized(box_px, along_length, factor, side));
                }
            }
        }
        out
    }

    /// This pose with its length and width times `factor` (the same apparent aspect),
    /// centre and orientation unchanged.
    pub fn scaled(&self, factor: f64) -> Self {
        Self {
            alpha: self.alpha / factor,
            ..*self
        }
    }

    /// This pose with its length (`along_length`) or its width times `factor`, for a
    /// `box_px` photo box: about the centre (`side` 0) or with the edge at `-side` of
    /// that axis fixed (`side` ±0.5), the centre moving by `side` times the change.
    pub fn resized(&self, box_px: [f64; 2], along_length: bool, factor: f64, side: f64) -> Self {
        let [length, width] = self.size_mm(box_px[0], box_px[1]);
        let mut q = *self;
        let (axis, extent) = if along_length {
            // β = α·k stays: only the length changes.
            q.alpha /= factor;
            q.k *= factor;
            (Vector3::x(), length)
        } else {
            q.k /= factor;
            (Vector3::y(), width)
        };
        q.position += self.rotation() * axis * (side * (factor - 1.0) * extent);
        q
    }

    /// This pose turned by `angle` (radians) about its own `axis` (model coordinates)
    /// through its centre, size unchanged.
    pub fn turned(&self, axis: Vector3<f64>, angle: f64) -> Self {
        let rotation = self.rotation() * UnitQuaternion::from_scaled_axis(axis * angle);
        let [_, x, y, z] = wxyz(&rotation);
        Self {
            eps: Vector3::new(x, y, z),
            ..*self
        }
    }

    /// This pose turned by `angle` about its own x or y axis (`about_x`), the other axis
    /// stretched so that its image keeps its extent across the left camera's line of
    /// sight (`left_from_hand` the hand–eye transform, `box_px` the photo box).
    pub fn turned_in_view(&self, left_from_hand: &Isometry3<f64>, box_px: [f64; 2], about_x: bool, angle: f64) -> Self {
        let sight = self.sight(left_from_hand).normalize();
        let (axis, other) = if about_x {
            (Vector3::x(), Vector3::y())
        } else {
            (Vector3::y(), Vector3::x())
        };
        let across = |q: &Self| {
            let d = q.rotation() * other;
            (d - sight * d.dot(&sight)).norm()
        };
        let q = self.turned(axis, angle);
        let stretch = (across(self) / across(&q).max(0.2)).clamp(0.5, 2.0);
        q.resized(box_px, !about_x, stretch, 0.0)
    }

    /// The orientation as `[w, x, y, z]` with `w ≥ 0`.
    pub fn orientation_wxyz(&self) -> [f64; 4] {
        wxyz(&self.rotation())
    }
}

/// A unit quaternion as `[w, x, y, z]` with `w ≥ 0` (the contract's output form).
fn wxyz(q: &UnitQuaternion<f64>) -> [f64; 4] {
    w_nonnegative([q.w, q.i, q.j, q.k])
}

/// Angle between two rotations, degrees.
pub fn rotation_error_deg(a: &UnitQuaternion<f64>, b: &UnitQuaternion<f64>) -> f64 {
    a.angle_to(b).to_degrees()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn epsilon_gives_unit_quaternion_with_positive_scalar() {
        let p = PoseSize {
            position: Vector3::zeros(),
            eps: Vector3::new(0.0, 0.0, (0.5f64).sqrt()),
            alpha: 2.0,
            k: 0.5,
        };
        // 90° about z: x axis goes to y.
        let v = p.rotation() * Vector3::x();
        assert!((v - Vector3::y()).norm() < 1e-12);
        assert_eq!(p.size_mm(434.0, 494.0), [217.0, 494.0]);
        let big = PoseSize {
            eps: Vector3::new(2.0, 0.0, 0.0),
            ..p
        };
        assert!((big.rotation().angle() - std::f64::consts::PI).abs() < 1e-12);
    }

    #[test]
    fn half_turned_is_upside_down_in_the_same_place_and_plane() {
        let iso = Isometry3::new(Vector3::new(10.0, -20.0, 600.0), Vector3::new(0.3, -0.2, 2.5));
        let p = PoseSize::from_pose(&iso, [80.0, 120.0], 200.0, 240.0);
        let q = p.half_turned();
        assert!((q.position - p.position).norm() < 1e-9);
        assert_eq!((q.alpha, q.k), (p.alpha, p.k));
        let (rp, rq) = (p.rotation(), q.rotation());
        // The same normal, the model's x and y axes reversed.
        assert!((rq * Vector3::z() - rp * Vector3::z()).norm() < 1e-9);
        assert!((rq * Vector3::x() + rp * Vector3::x()).norm() < 1e-9);
        assert!((rotation_error_deg(&q.half_turned().rotation(), &rp)).abs() < 1e-6);
    }

    #[test]
    fn from_pose_round_trips() {
        let iso = Isometry3::new(Vector3::new(10.0, -20.0, 600.0), Vector3::new(0.3, -0.2, 2.5));
        let p = PoseSize::from_pose(&iso, [80.0, 120.0], 200.0, 240.0);
        assert!((p.hand_from_model().to_homogeneous() - iso.to_homogeneous()).norm() < 1e-9);
        let s = p.size_mm(200.0, 240.0);
        assert!((s[0] - 80.0).abs() < 1e-9 && (s[1] - 120.0).abs() < 1e-9);
        assert!(p.orientation_wxyz()[0] >= 0.0);
    }

    #[test]
    fn a_tilt_turns_about_the_centre_and_stretches_across_the_axis() {
        // Facing the camera, 600 mm ahead; the hand frame is the camera frame.
        let facing = Isometry3::new(Vector3::new(20.0, -10.0, 600.0), Vector3::zeros());
        let p = PoseSize::from_pose(&facing, [100.0, 80.0], 200.0, 160.0);
        let tilt = 30f64.to_radians();
        let q = p.tilted(&Isometry3::identity(), Vector3::x(), tilt);
        assert!((q.position - p.position).norm() < 1e-9, "the centre stays");
        assert!((q.rotation().angle_to(&p.rotation()) - tilt).abs() < 1e-9);
        // About x the width (model y) foreshortens: it grows by 1 / cos 30°, the length stays.
        let [l, b] = q.size_mm(200.0, 160.0);
        assert!((l - 100.0).abs() < 1e-9, "{l}");
        assert!((b - 80.0 / tilt.cos()).abs() < 1e-9, "{b}");
    }

    #[test]
    fn a_turn_in_view_keeps_the_image_and_turns_back_to_the_start() {
        // Tilted 20° about its width, 600 mm straight ahead; the hand frame is the camera frame.
        let tilted = Isometry3::new(Vector3::new(0.0, 0.0, 600.0), Vector3::y() * 20f64.to_radians());
        let p = PoseSize::from_pose(&tilted, [100.0, 80.0], 200.0, 160.0);
        let (hand, box_px) = (Isometry3::identity(), [200.0, 160.0]);
        let q = p.turned_in_view(&hand, box_px, false, 30f64.to_radians());
        assert!((q.position - p.position).norm() < 1e-9, "the centre stays");
        // At 50° the length spans what 100 mm did at 20°; the width is not touched.
        let [l, b] = q.size_mm(200.0, 160.0);
        let expected = 100.0 * 20f64.to_radians().cos() / 50f64.to_radians().cos();
        assert!((l - expected).abs() < 1e-6 && (b - 80.0).abs() < 1e-9, "{l} {b}");
        let back = q.turned_in_view(&hand, box_px, false, -30f64.to_radians());
        assert!(back.rotation().angle_to(&p.rotation()) < 1e-9);
        assert!((back.size_mm(200.0, 160.0)[0] - 100.0).abs() < 1e-6);
    }
}
