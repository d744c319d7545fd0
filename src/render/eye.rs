//! One camera's view of the scene: the nearest surface along each pixel's rays, with
//! edge pixels supersampled, shaded into rows of the side-by-side frame.

use std::sync::Arc;

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use super::noise::Noise;
use super::rays::RayTable;
use super::surface::{Look, Plane, Surface};
use super::texture::{MipTexture, Wrap};
use super::{Background, Band, Occluder, OccluderFill, Region, Scene, Textures, CARDBOARD};
use crate::camera::Intrinsics;

/// One camera's view of the scene: surfaces in front-to-back priority (occluder, card,
/// wall); the nearest hit wins regardless.
pub(super) struct Eye<'a> {
    rays: Arc<RayTable>,
    /// Occluder, card, wall: the first `n` are set.
    surfaces: [Option<Surface<'a>>; 3],
}

pub(super) const MISS: u8 = u8::MAX;

/// A pixel corner: its ray, the surface it hits (`MISS` = none) and the hit point there.
#[derive(Debug, Clone, Copy)]
pub(super) struct Corner {
    ray: Vector3<f64>,
    id: u8,
    xy: [f64; 2],
}

impl<'a> Eye<'a> {
    pub(super) fn new(
        cam: Intrinsics,
        w: usize,
        h: usize,
        cam_from_left: &Isometry3<f64>,
        left_from_model: &Isometry3<f64>,
        scene: &'a Scene,
        textures: &'a Textures,
    ) -> Self {
        let found = [
            scene
                .occluder
                .as_ref()
                .and_then(|o| occluder_surface(o, textures.occluder.as_ref(), cam_from_left)),
            card_surface(scene, &textures.card, &(cam_from_left * left_from_model)),
            Some(wall_surface(&scene.background, cam_from_left)),
        ];
        // Occluder, card, wall: the first `n` are set.
        let mut surfaces = [None, None, None];
        for (slot, surface) in surfaces.iter_mut().zip(found.into_iter().flatten()) {
            *slot = Some(surface);
        }
        Self {
            rays: super::rays::table(&cam, w, h),
            surfaces,
        }
    }

    pub(super) fn surface(&self, k: usize) -> Option<&Surface<'a>> {
        self.surfaces.get(k).and_then(Option::as_ref)
    }

    /// Nearest surface hit by ray `d`: `(surface index, x, y)`.
    #[inline]
    pub(super) fn trace(&self, d: &Vector3<f64>) -> Option<(usize, f64, f64)> {
        let mut best: Option<(usize, f64, f64, f64)> = None;
        for (k, s) in self.surfaces.iter().flatten().enumerate() {
            if let Some((lam, x, y)) = s.hit(d) {
                if best.is_none_or(|b| lam < b.1) {
                    best = Some((k, lam, x, y));
                }
            }
        }
        best.map(|(k, _, x, y)| (k, x, y))
    }

    /// Corner rays, their surfaces and hit points for corner row `jc` (`v = jc − ½`),
    /// columns `i0..i0 + row.len()`.
    pub(super) fn corner_row(&self, jc: usize, row: &mut [Corner], i0: usize) {
        for (i, c) in row.iter_mut().enumerate() {
            let [x, y] = self.rays.corner(i0 + i, jc);
            c.ray = Vector3::new(x, y, 1.0);
            (c.id, c.xy) = match self.trace(&c.ray) {
                Some((k, x, y)) => (k as u8, [x, y]),
                None => (MISS, [0.0; 2]),
            };
        }
    }

    /// Renders `region` of this eye (`eye` 0 left, 1 right) within the rows of `chunk`,
    /// a band of the side-by-side frame; `top` and `bot` are scratch rows.
    pub(super) fn render_band(
        &self,
        chunk: &mut [u8],
        band: &Band,
        eye: usize,
        region: &Region,
        top: &mut Vec<Corner>,
        bot: &mut Vec<Corner>,
    ) {
        let Band { y0, w, sigma, seed } = *band;
        let row_bytes = 2 * w * 3;
        let rows = chunk.len() / row_bytes;
        let (c0, c1) = (region.cols.start.min(w), region.cols.end.min(w));
        let (r0, r1) = (region.rows.start.max(y0), region.rows.end.min(y0 + rows));
        if c0 >= c1 || r0 >= r1 {
            return;
        }
        let blank = Corner {
            ray: Vector3::zeros(),
            id: MISS,
            xy: [0.0; 2],
        };
        for row in [&mut *top, &mut *bot] {
            row.clear();
            row.resize(w + 1, blank);
        }
        self.corner_row(r0, &mut top[c0..=c1], c0);
        for j in r0..r1 {
            let r = j - y0;
            self.corner_row(j + 1, &mut bot[c0..=c1], c0);
            let row = &mut chunk[r * row_bytes + eye * w * 3..r * row_bytes + (eye + 1) * w * 3];
            let mut noise = Noise::new(seed, eye, j, sigma);
            for i in c0..c1 {
                let q = [&top[i], &top[i + 1], &bot[i], &bot[i + 1]];
                let corners = [q[0].ray, q[1].ray, q[2].ray, q[3].ray];
                let id = q[0].id;
                let c = if id == q[1].id && id == q[2].id && id == q[3].id {
                    // One surface under the whole pixel (it is convex): shade its centre.
                    match self.surface(id as usize) {
                        Some(s) => {
                            let d = blend(&corners, 0.5, 0.5);
                            match s.plane.intersect(&d) {
                                Some((_, x, y)) => {
                                    let fp = s.footprint_xy(&[q[0].xy, q[1].xy, q[2].xy, q[3].xy]);
                                    s.shade(x, y, fp)
                                }
                                None => [0.0; 3],
                            }
                        }
                        None => [0.0; 3],
                    }
                } else {
                    self.supersample(&corners)
                };
                let o = i * 3;
                for k in 0..3 {
                    row[o + k] = to_u8(c[k] + noise.next());
                }
            }
            std::mem::swap(top, bot);
        }
    }

    /// 4×4 supersampling of an edge pixel.
    pub(super) fn supersample(&self, corners: &[Vector3<f64>; 4]) -> [f32; 3] {
        const N: usize = 4;
        let mut footprints = [f64::NAN; 3];
        let mut acc = [0.0f32; 3];
        for b in 0..N {
            let fv = (b as f64 + 0.5) / N as f64;
            for a in 0..N {
                let fu = (a as f64 + 0.5) / N as f64;
                let d = blend(corners, fu, fv);
                if let Some((k, x, y, s)) = self.trace(&d).and_then(|(k, x, y)| Some((k, x, y, self.surface(k)?))) {
                    let fp = match footprints.get_mut(k) {
                        Some(f) => {
                            if f.is_nan() {
                                *f = s.footprint(corners) / N as f64;
                            }
                            *f
                        }
                        None => s.footprint(corners) / N as f64,
                    };
                    let c = s.shade(x, y, fp);
                    for q in 0..3 {
                        acc[q] += c[q];
                    }
                }
            }
        }
        acc.map(|v| v / (N * N) as f32)
    }
}

/// Ray through the point at fractions `(fu, fv)` of a pixel, from its corner rays
/// `[top-left, top-right, bottom-left, bottom-right]` (bilinear).
#[inline]
pub(super) fn blend(c: &[Vector3<f64>; 4], fu: f64, fv: f64) -> Vector3<f64> {
    let top = c[0] + (c[1] - c[0]) * fu;
    let bot = c[2] + (c[3] - c[2]) * fu;
    top + (bot - top) * fv
}

/// Rounds and saturates a colour value.
#[inline]
pub(super) fn to_u8(v: f32) -> u8 {
    // `as` truncates towards zero; the value is non-negative after the clamp.
    (v.clamp(0.0, 255.0) + 0.5) as u8
}

/// The occluder's surface, `None` when it has no (finite, positive) size.
fn occluder_surface<'a>(
    o: &Occluder,
    texture: Option<&'a MipTexture>,
    cam_from_left: &Isometry3<f64>,
) -> Option<Surface<'a>> {
    let [sx, sy] = o.size_mm;
    if !(sx > 0.0 && sy > 0.0 && sx.is_finite() && sy.is_finite()) {
        return None;
    }
    let look = match (&o.fill, texture) {
        (OccluderFill::Texture(_), Some(t)) => Look::Tex {
            tex: t,
            wrap: Wrap::Clamp,
            scale: [t.width() / sx, t.height() / sy],
            offset: [0.5 * t.width(), 0.5 * t.height()],
        },
        (OccluderFill::Solid(c), _) => Look::Solid(c.map(f32::from)),
        (OccluderFill::Texture(_), None) => Look::Solid([128.0; 3]),
    };
    Some(Surface {
        plane: Plane::new(&(cam_from_left * o.left_from_occluder)),
        half: Some([0.5 * sx, 0.5 * sy]),
        look,
        gain: 1.0,
    })
}

/// The card's surface in a camera at `cam_from_model`, `None` when it has no (finite,
/// positive) size: the photo's texture from the front, cardboard from behind.
fn card_surface<'a>(scene: &Scene, texture: &'a MipTexture, cam_from_model: &Isometry3<f64>) -> Option<Surface<'a>> {
    let [l, b] = scene.card.size_mm;
    if !(l > 0.0 && b > 0.0 && l.is_finite() && b.is_finite()) {
        return None;
    }
    let plane = Plane::new(cam_from_model);
    // The textured face looks along −z_M: visible iff the camera is on the −z side.
    let look = if plane.origin.z < 0.0 {
        Look::Tex {
            tex: texture,
            wrap: Wrap::Clamp,
            scale: [texture.width() / l, texture.height() / b],
            offset: [0.5 * texture.width(), 0.5 * texture.height()],
        }
    } else {
        Look::Solid(CARDBOARD.map(f32::from))
    };
    let gain = if scene.brightness.is_finite() && scene.brightness >= 0.0 {
        scene.brightness as f32
    } else {
        1.0
    };
    Some(Surface {
        plane,
        half: Some([0.5 * l, 0.5 * b]),
        look,
        gain,
    })
}

/// The wall: an unbounded plane facing the camera, its texture mirrored beyond its edges.
fn wall_surface<'a>(bg: &'a Background, cam_from_left: &Isometry3<f64>) -> Surface<'a> {
    let mip = bg.mip();
    let wall = Isometry3::from_parts(
        Translation3::new(0.0, 0.0, bg.distance_mm()),
        UnitQuaternion::identity(),
    );
    Surface {
        plane: Plane::new(&(cam_from_left * wall)),
        half: None,
        look: Look::Tex {
            tex: mip,
            wrap: Wrap::Mirror,
            scale: [1.0 / bg.texel_mm(), 1.0 / bg.texel_mm()],
            offset: [0.5 * mip.width(), 0.5 * mip.height()],
        },
        gain: 1.0,
    }
}
