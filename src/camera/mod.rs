//! Pinhole cameras with Brown–Conrady distortion and the calibrated stereo rig.
//!
//! Projection is always forward (3D point → distorted pixel), as the paper does: the
//! images are never rectified. The inverse (pixel → ray) exists for the renderer.

pub mod calibration;
pub mod settings;

use nalgebra::{Isometry3, Point2, Point3, Vector3};

/// Intrinsics of one camera in OpenCV convention (pixels; distortion k1 k2 p1 p2 k3).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intrinsics {
    /// Horizontal focal length, pixels.
    pub fx: f64,
    /// Vertical focal length, pixels.
    pub fy: f64,
    /// Principal point column, pixels from the left image edge.
    pub cx: f64,
    /// Principal point row, pixels from the top image edge.
    pub cy: f64,
    /// First radial distortion coefficient (r² term).
    pub k1: f64,
    /// Second radial distortion coefficient (r⁴ term).
    pub k2: f64,
    /// First tangential distortion coefficient.
    pub p1: f64,
    /// Second tangential distortion coefficient.
    pub p2: f64,
    /// Third radial distortion coefficient (r⁶ term).
    pub k3: f64,
}

impl Intrinsics {
    /// A distortion-free camera (tests, hand computations).
    pub fn pinhole(fx: f64, fy: f64, cx: f64, cy: f64) -> Self {
        Self {
            fx,
            fy,
            cx,
            cy,
            k1: 0.0,
            k2: 0.0,
            p1: 0.0,
            p2: 0.0,
            k3: 0.0,
        }
    }

    /// Applies Brown–Conrady distortion to normalised image coordinates `(x, y) = (X/Z, Y/Z)`.
    #[inline]
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        let xd = x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x);
        let yd = y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y;
        (xd, yd)
    }

    /// Inverts [`Intrinsics::distort`] by fixed-point iteration (converges for real lenses
    /// within the image, to below 1e-6 px at HD).
    pub fn undistort(&self, xd: f64, yd: f64) -> (f64, f64) {
        let (mut x, mut y) = (xd, yd);
        for _ in 0..200 {
            let (px, py) = (x, y);
            let r2 = x * x + y * y;
            let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
            let dx = 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x);
            let dy = self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y;
            x = (xd - dx) / radial;
            y = (yd - dy) / radial;
            if (x - px).abs() + (y - py).abs() < 1e-13 {
                break;
            }
        }
        (x, y)
    }

    /// Projects a point in this camera's frame to a (distorted) pixel; `None` behind the camera.
    #[inline]
    pub fn project(&self, p: &Point3<f64>) -> Option<Point2<f64>> {
        if p.z <= 1e-9 {
            return None;
        }
        let (xd, yd) = self.distort(p.x / p.z, p.y / p.z);
        Some(Point2::new(self.fx * xd + self.cx, self.fy * yd + self.cy))
    }

    /// The viewing ray through pixel `(u, v)` as a direction with `z = 1`.
    pub fn ray(&self, u: f64, v: f64) -> Vector3<f64> {
        let (x, y) = self.undistort((u - self.cx) / self.fx, (v - self.cy) / self.fy);
        Vector3::new(x, y, 1.0)
    }

    /// The same camera for an image scaled by `s` (image pyramids): pixel centres follow
    /// the `(u + 0.5)·s − 0.5` convention of box downsampling.
    pub fn scaled(&self, s: f64) -> Self {
        Self {
            fx: self.fx * s,
            fy: self.fy * s,
            cx: (self.cx + 0.5) * s - 0.5,
            cy: (self.cy + 0.5) * s - 0.5,
            ..*self
        }
    }
}

/// The calibrated stereo pair for one resolution: both cameras and the right camera's
/// pose. `right_from_left` maps left-camera coordinates into right-camera coordinates.
#[derive(Debug, Clone, PartialEq)]
pub struct StereoRig {
    /// Image width of one eye, pixels.
    pub width: u32,
    /// Image height of one eye, pixels.
    pub height: u32,
    /// Intrinsics of the left camera.
    pub left: Intrinsics,
    /// Intrinsics of the right camera.
    pub right: Intrinsics,
    /// Maps left-camera coordinates into right-camera coordinates (translation in mm).
    pub right_from_left: Isometry3<f64>,
}

impl StereoRig {
    /// Projects a left-camera point into both images.
    pub fn project_both(&self, p_left: &Point3<f64>) -> (Option<Point2<f64>>, Option<Point2<f64>>) {
        let p_right = self.right_from_left * p_left;
        (self.left.project(p_left), self.right.project(&p_right))
    }

    /// The rig for images scaled by `s` (pyramid level); the extrinsics are unchanged.
    pub fn scaled(&self, s: f64) -> Self {
        Self {
            width: ((self.width as f64) * s).round() as u32,
            height: ((self.height as f64) * s).round() as u32,
            left: self.left.scaled(s),
            right: self.right.scaled(s),
            right_from_left: self.right_from_left,
        }
    }

    /// Distance between the optical centres, mm.
    pub fn baseline_mm(&self) -> f64 {
        self.right_from_left.inverse().translation.vector.norm()
    }
}

/// Rotation quaternions as files and messages write them: Hamilton `[w, x, y, z]` arrays.
/// Everything that reads or writes one checks and normalises it here.
pub mod geometry {
    /// Largest deviation from 1 of the norm of a quaternion read from a file
    /// (configuration, scenes, recorded truth), which rounds to a few decimals.
    pub const FILE_UNIT_TOLERANCE: f64 = 1e-3;

    /// The Euclidean norm of `q`.
    pub fn wxyz_norm(q: [f64; 4]) -> f64 {
        q.iter().map(|v| v * v).sum::<f64>().sqrt()
    }

    /// True when the norm of `q` is finite and within `tolerance` of 1.
    pub fn is_unit_wxyz(q: [f64; 4], tolerance: f64) -> bool {
        let norm = wxyz_norm(q);
        norm.is_finite() && (norm - 1.0).abs() <= tolerance
    }

    /// The same rotation with `w ≥ 0` (`q` and `−q` are one rotation), the form
    /// photopose writes.
    pub fn w_nonnegative(q: [f64; 4]) -> [f64; 4] {
        let sign = if q[0] < 0.0 { -1.0 } else { 1.0 };
        q.map(|v| sign * v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    fn lens() -> Intrinsics {
        Intrinsics {
            fx: 700.0,
            fy: 701.0,
            cx: 640.0,
            cy: 360.0,
            k1: -0.17,
            k2: 0.025,
            p1: 0.0004,
            p2: -0.0003,
            k3: -0.001,
        }
    }

    #[test]
    fn pinhole_projection_matches_hand_computation() {
        let cam = Intrinsics::pinhole(700.0, 700.0, 640.0, 360.0);
        // (100, -50, 500) mm → x = 0.2, y = -0.1 → u = 640 + 140, v = 360 - 70.
        let p = cam.project(&Point3::new(100.0, -50.0, 500.0)).unwrap();
        assert!((p.x - 780.0).abs() < 1e-9 && (p.y - 290.0).abs() < 1e-9);
        assert!(cam.project(&Point3::new(0.0, 0.0, -1.0)).is_none());
    }

    #[test]
    fn distortion_matches_hand_computation() {
        let cam = lens();
        // x = 0.2, y = -0.1: r² = 0.05,
        // radial = 1 − 0.17·0.05 + 0.025·0.0025 − 0.001·0.000125 = 0.991562375
        let (x, y) = (0.2, -0.1);
        let radial = 0.991_562_375;
        let xd = x * radial + 2.0 * 0.0004 * x * y + (-0.0003) * (0.05 + 2.0 * x * x);
        let yd = y * radial + 0.0004 * (0.05 + 2.0 * y * y) + 2.0 * (-0.0003) * x * y;
        let p = cam.project(&Point3::new(100.0, -50.0, 500.0)).unwrap();
        assert!((p.x - (700.0 * xd + 640.0)).abs() < 1e-9);
        assert!((p.y - (701.0 * yd + 360.0)).abs() < 1e-9);
        // Barrel distortion pulls the point towards the centre.
        assert!(p.x < 780.0);
    }

    #[test]
    fn ray_inverts_projection() {
        let cam = lens();
        for &(u, v) in &[(0.0, 0.0), (1279.0, 719.0), (640.0, 360.0), (100.0, 650.0)] {
            let r = cam.ray(u, v);
            let p = cam.project(&Point3::from(r * 800.0)).unwrap();
            assert!((p.x - u).abs() < 1e-6 && (p.y - v).abs() < 1e-6, "{u},{v} → {p}");
        }
    }

    #[test]
    fn right_camera_sees_point_shifted_by_disparity() {
        let rig = StereoRig {
            width: 1280,
            height: 720,
            left: Intrinsics::pinhole(700.0, 700.0, 640.0, 360.0),
            right: Intrinsics::pinhole(700.0, 700.0, 640.0, 360.0),
            right_from_left: Isometry3::from_parts(Translation3::new(-120.0, 0.0, 0.0), UnitQuaternion::identity()),
        };
        let (l, r) = rig.project_both(&Point3::new(0.0, 0.0, 700.0));
        let (l, r) = (l.unwrap(), r.unwrap());
        // disparity = f·b/z = 700·120/700 = 120 px, right image point is further left.
        assert!((l.x - r.x - 120.0).abs() < 1e-9);
        assert!((rig.baseline_mm() - 120.0).abs() < 1e-9);
    }

    #[test]
    fn scaled_camera_halves_pixel_coordinates() {
        let cam = lens();
        let half = cam.scaled(0.5);
        let p = Point3::new(30.0, 20.0, 600.0);
        let full = cam.project(&p).unwrap();
        let h = half.project(&p).unwrap();
        assert!(((full.x + 0.5) * 0.5 - 0.5 - h.x).abs() < 1e-9);
        assert!(((full.y + 0.5) * 0.5 - 0.5 - h.y).abs() < 1e-9);
    }

    #[test]
    fn quaternions_are_checked_and_written_with_w_nonnegative() {
        use geometry::*;
        let half = std::f64::consts::FRAC_1_SQRT_2;
        assert!(is_unit_wxyz([half, 0.0, -half, 0.0], 1e-12));
        assert!(is_unit_wxyz([1.0005, 0.0, 0.0, 0.0], FILE_UNIT_TOLERANCE));
        assert!(!is_unit_wxyz([1.01, 0.0, 0.0, 0.0], FILE_UNIT_TOLERANCE));
        assert!(!is_unit_wxyz([f64::NAN, 0.0, 0.0, 0.0], 1.0));
        assert!(!is_unit_wxyz([f64::INFINITY, 0.0, 0.0, 0.0], 1.0));
        assert_eq!(wxyz_norm([0.0, 3.0, 0.0, 4.0]), 5.0);
        assert_eq!(w_nonnegative([-0.5, 0.5, -0.5, 0.5]), [0.5, -0.5, 0.5, -0.5]);
        assert_eq!(w_nonnegative([0.5, 0.5, -0.5, 0.5]), [0.5, 0.5, -0.5, 0.5]);
    }
}
