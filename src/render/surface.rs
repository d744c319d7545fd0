//! The surfaces a ray can hit (occluder, card, wall): planes, their extent and how they
//! look (a solid colour or a mip-mapped texture).

use nalgebra::{Isometry3, Matrix3, Vector3};

use super::texture::{MipTexture, Wrap};

/// A plane given by its frame: `rot`/`origin` map camera coordinates into the plane's
/// frame, in which the plane is `z = 0`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Plane {
    pub(super) rot: Matrix3<f64>,
    pub(super) origin: Vector3<f64>,
}

impl Plane {
    pub(super) fn new(cam_from_surface: &Isometry3<f64>) -> Self {
        let inv = cam_from_surface.inverse();
        Self {
            rot: inv.rotation.to_rotation_matrix().into_inner(),
            origin: inv.translation.vector,
        }
    }

    /// Intersects the ray `λ·d` (λ > 0): `(λ, x, y)` in plane coordinates.
    #[inline]
    pub(super) fn intersect(&self, d: &Vector3<f64>) -> Option<(f64, f64, f64)> {
        let dm = self.rot * d;
        let lam = -self.origin.z / dm.z;
        if !lam.is_finite() || lam <= 0.0 {
            return None;
        }
        Some((lam, self.origin.x + lam * dm.x, self.origin.y + lam * dm.y))
    }
}

#[derive(Debug, Clone, Copy)]
pub(super) enum Look<'a> {
    Solid([f32; 3]),
    /// Texel coordinates `u = x·scale[0] + offset[0]`, `v = y·scale[1] + offset[1]`.
    Tex {
        tex: &'a MipTexture,
        wrap: Wrap,
        scale: [f64; 2],
        offset: [f64; 2],
    },
}

#[derive(Debug, Clone, Copy)]
pub(super) struct Surface<'a> {
    pub(super) plane: Plane,
    /// Half extents; `None` = unbounded.
    pub(super) half: Option<[f64; 2]>,
    pub(super) look: Look<'a>,
    pub(super) gain: f32,
}

impl Surface<'_> {
    #[inline]
    pub(super) fn hit(&self, d: &Vector3<f64>) -> Option<(f64, f64, f64)> {
        let (lam, x, y) = self.plane.intersect(d)?;
        match self.half {
            Some([hx, hy]) if x.abs() > hx || y.abs() > hy => None,
            _ => Some((lam, x, y)),
        }
    }

    /// Texture footprint (level-0 texels) of the pixel area spanned by four corner rays
    /// `[top-left, top-right, bottom-left, bottom-right]`.
    pub(super) fn footprint(&self, corners: &[Vector3<f64>; 4]) -> f64 {
        let mut xy = [[0.0f64; 2]; 4];
        for (p, c) in xy.iter_mut().zip(corners) {
            let Some((_, x, y)) = self.plane.intersect(c) else {
                return 1.0;
            };
            *p = [x, y];
        }
        self.footprint_xy(&xy)
    }

    /// Texture footprint from the pixel corners' plane coordinates (mm).
    #[inline]
    pub(super) fn footprint_xy(&self, xy: &[[f64; 2]; 4]) -> f64 {
        let Look::Tex { scale, .. } = self.look else {
            return 1.0;
        };
        let eu = [
            0.5 * scale[0] * (xy[1][0] - xy[0][0] + xy[3][0] - xy[2][0]),
            0.5 * scale[1] * (xy[1][1] - xy[0][1] + xy[3][1] - xy[2][1]),
        ];
        let ev = [
            0.5 * scale[0] * (xy[2][0] - xy[0][0] + xy[3][0] - xy[1][0]),
            0.5 * scale[1] * (xy[2][1] - xy[0][1] + xy[3][1] - xy[1][1]),
        ];
        (eu[0] * eu[0] + eu[1] * eu[1])
            .max(ev[0] * ev[0] + ev[1] * ev[1])
            .sqrt()
    }

    #[inline]
    pub(super) fn shade(&self, x: f64, y: f64, footprint: f64) -> [f32; 3] {
        let c = match self.look {
            Look::Solid(c) => c,
            Look::Tex {
                tex,
                wrap,
                scale,
                offset,
            } => tex.sample(x * scale[0] + offset[0], y * scale[1] + offset[1], footprint, wrap),
        };
        if self.gain == 1.0 {
            c
        } else {
            c.map(|v| v * self.gain)
        }
    }
}
