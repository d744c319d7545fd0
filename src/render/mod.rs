//! Synthetic stereo camera: renders a photo card in front of a textured wall through the
//! calibrated, distorted ZED cameras (the ground-truth source of every accuracy test).
//!
//! Conventions: millimetres; OpenCV camera frames (x right, y down, z forward); the left
//! camera is the reference. The card's model frame Σ_M has its origin at the card centre,
//! x along the photo's columns, y along its rows and z = x × y; its textured face is the one
//! whose normal is −z_M. A card point `(x, y, 0)` shows the texture at
//! `((x/L + 0.5)·w, (y/B + 0.5)·h)` (continuous texel coordinates, `[L, B]` = card size).
//!
//! Method: inverse mapping. Every output pixel's ray ([`Intrinsics::ray`], i.e. through the
//! lens distortion) is intersected with the occluder, the card and the wall; the nearest hit
//! is shaded from a mip-mapped texture whose level follows the pixel footprint. Pixels whose
//! four corners do not all hit the same surface are supersampled 4×4 (anti-aliased edges).
//! Optional seeded Gaussian noise and card brightness complete the frame. Rows are rendered
//! in parallel bands; the output is side-by-side (left eye in the left half).

mod background;
pub mod scene;
mod texture;

use std::sync::Mutex;

use image::RgbImage;
use nalgebra::{Isometry3, Matrix3, Point3, Translation3, UnitQuaternion, Vector3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use crate::camera::{Intrinsics, StereoRig};
use texture::{MipTexture, Wrap};

pub use background::Background;
pub use scene::{ResolutionName, SceneError, SceneSpec};

/// Colour of the card's untextured back face (plain grey cardboard).
pub const CARDBOARD: [u8; 3] = [150, 146, 138];

/// How far the occluder built by [`Occluder::covering`] sits towards the camera: its
/// distance is this fraction of the card's.
const OCCLUDER_DEPTH_FACTOR: f64 = 0.85;

/// The target: a flat photo card of size `size_mm = [L, B]` posed in the hand frame.
#[derive(Debug, Clone)]
pub struct Card {
    /// The photo's box crop (shown unmirrored on the −z_M face).
    pub texture: RgbImage,
    /// Card model frame Σ_M in the hand frame.
    pub hand_from_model: Isometry3<f64>,
    /// `[L, B]`: extent along model x (photo columns) and model y (photo rows), mm.
    pub size_mm: [f64; 2],
}

/// Appearance of an [`Occluder`].
#[derive(Debug, Clone)]
pub enum OccluderFill {
    Solid([u8; 3]),
    /// Stretched over the whole rectangle (same mapping as the card).
    Texture(RgbImage),
}

/// An opaque rectangle (both faces alike) in the left-camera frame, centred on its local
/// origin, spanning its local x/y axes.
#[derive(Debug, Clone)]
pub struct Occluder {
    pub left_from_occluder: Isometry3<f64>,
    /// Extent along local x and y, mm.
    pub size_mm: [f64; 2],
    pub fill: OccluderFill,
}

impl Occluder {
    /// An occluder parallel to the card, 15 % nearer to the left camera, that hides
    /// `fraction` of the card's area in the left image: a band along one card side (chosen
    /// by `seed`) that also sticks out beyond the card. `None` for `fraction <= 0` or a
    /// degenerate card; fractions above 1 are clamped.
    pub fn covering(
        left_from_model: &Isometry3<f64>,
        card_size_mm: [f64; 2],
        fraction: f64,
        fill: OccluderFill,
        seed: u64,
    ) -> Option<Occluder> {
        let [l, b] = card_size_mm;
        if !(fraction > 0.0) || !(l > 0.0 && b > 0.0) || !l.is_finite() || !b.is_finite() {
            return None;
        }
        let f = fraction.min(1.0);
        let side = StdRng::seed_from_u64(seed ^ 0x6f63_636c).random_range(0..4u32);
        let m = 0.25; // overhang beyond the card, as a fraction of its size
        // Band [a, c] across the covered axis (model units), full span plus overhang along
        // the other one; the card's part of it is exactly f·L·B.
        let (a, c) = (0.5 - f, 0.5 + m);
        let (centre, size) = match side {
            0 => ([0.5 * (a + c) * l, 0.0], [(c - a) * l, (1.0 + 2.0 * m) * b]),
            1 => ([-0.5 * (a + c) * l, 0.0], [(c - a) * l, (1.0 + 2.0 * m) * b]),
            2 => ([0.0, 0.5 * (a + c) * b], [(1.0 + 2.0 * m) * l, (c - a) * b]),
            _ => ([0.0, -0.5 * (a + c) * b], [(1.0 + 2.0 * m) * l, (c - a) * b]),
        };
        // Scaling about the camera centre keeps the left-image projection unchanged.
        let s = OCCLUDER_DEPTH_FACTOR;
        let p = left_from_model * Point3::new(centre[0], centre[1], 0.0);
        Some(Occluder {
            left_from_occluder: Isometry3::from_parts(
                Translation3::from(p.coords * s),
                left_from_model.rotation,
            ),
            size_mm: [size[0] * s, size[1] * s],
            fill,
        })
    }
}

/// Everything the synthetic camera sees.
#[derive(Debug, Clone)]
pub struct Scene {
    pub card: Card,
    pub background: Background,
    /// Standard deviation of additive Gaussian pixel noise, grey levels (0 = none).
    pub noise_sigma: f64,
    /// Multiplies the card's colour (1.0 = unchanged).
    pub brightness: f64,
    pub occluder: Option<Occluder>,
    /// Seed of the pixel noise.
    pub seed: u64,
}

/// Renders the side-by-side frame through the calibrated, distorted cameras.
pub fn render(rig: &StereoRig, left_from_hand: &Isometry3<f64>, scene: &Scene) -> RgbImage {
    let (w, h) = (rig.width as usize, rig.height as usize);
    let mut out = RgbImage::new(2 * rig.width, rig.height);
    if w == 0 || h == 0 {
        return out;
    }
    let card_tex = MipTexture::new(&scene.card.texture);
    let occ_tex = match &scene.occluder {
        Some(Occluder {
            fill: OccluderFill::Texture(t),
            ..
        }) => Some(MipTexture::new(t)),
        _ => None,
    };
    let left_from_model = left_from_hand * scene.card.hand_from_model;
    let eyes = [
        Eye::new(
            rig.left,
            &Isometry3::identity(),
            &left_from_model,
            scene,
            &card_tex,
            occ_tex.as_ref(),
        ),
        Eye::new(
            rig.right,
            &rig.right_from_left,
            &left_from_model,
            scene,
            &card_tex,
            occ_tex.as_ref(),
        ),
    ];
    let sigma = if scene.noise_sigma.is_finite() && scene.noise_sigma > 0.0 {
        scene.noise_sigma as f32
    } else {
        0.0
    };

    let threads = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
        .clamp(1, 64);
    let band_rows = h.div_ceil(threads * 4).max(1);
    let row_bytes = 2 * w * 3;
    let work = Mutex::new(out.chunks_mut(row_bytes * band_rows).enumerate());
    std::thread::scope(|s| {
        for _ in 0..threads {
            s.spawn(|| loop {
                let next = match work.lock() {
                    Ok(mut it) => it.next(),
                    Err(_) => None,
                };
                let Some((band, chunk)) = next else { break };
                let y0 = band * band_rows;
                for (e, eye) in eyes.iter().enumerate() {
                    eye.render_band(chunk, y0, w, e, sigma, scene.seed);
                }
            });
        }
    });
    out
}

/// A plane given by its frame: `rot`/`origin` map camera coordinates into the plane's
/// frame, in which the plane is `z = 0`.
#[derive(Debug, Clone, Copy)]
struct Plane {
    rot: Matrix3<f64>,
    origin: Vector3<f64>,
}

impl Plane {
    fn new(cam_from_surface: &Isometry3<f64>) -> Self {
        let inv = cam_from_surface.inverse();
        Self {
            rot: inv.rotation.to_rotation_matrix().into_inner(),
            origin: inv.translation.vector,
        }
    }

    /// Intersects the ray `λ·d` (λ > 0): `(λ, x, y)` in plane coordinates.
    #[inline]
    fn intersect(&self, d: &Vector3<f64>) -> Option<(f64, f64, f64)> {
        let dm = self.rot * d;
        let lam = -self.origin.z / dm.z;
        if !lam.is_finite() || lam <= 0.0 {
            return None;
        }
        Some((
            lam,
            self.origin.x + lam * dm.x,
            self.origin.y + lam * dm.y,
        ))
    }
}

#[derive(Debug, Clone, Copy)]
enum Look<'a> {
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
struct Surface<'a> {
    plane: Plane,
    /// Half extents; `None` = unbounded.
    half: Option<[f64; 2]>,
    look: Look<'a>,
    gain: f32,
}

impl Surface<'_> {
    #[inline]
    fn hit(&self, d: &Vector3<f64>) -> Option<(f64, f64, f64)> {
        let (lam, x, y) = self.plane.intersect(d)?;
        match self.half {
            Some([hx, hy]) if x.abs() > hx || y.abs() > hy => None,
            _ => Some((lam, x, y)),
        }
    }

    /// Texture footprint (level-0 texels) of the pixel area spanned by four corner rays
    /// `[top-left, top-right, bottom-left, bottom-right]`.
    fn footprint(&self, corners: &[Vector3<f64>; 4]) -> f64 {
        let Look::Tex { scale, .. } = self.look else {
            return 1.0;
        };
        let mut t = [[0.0f64; 2]; 4];
        for (k, c) in corners.iter().enumerate() {
            let Some((_, x, y)) = self.plane.intersect(c) else {
                return 1.0;
            };
            t[k] = [x * scale[0], y * scale[1]];
        }
        let eu = [
            0.5 * (t[1][0] - t[0][0] + t[3][0] - t[2][0]),
            0.5 * (t[1][1] - t[0][1] + t[3][1] - t[2][1]),
        ];
        let ev = [
            0.5 * (t[2][0] - t[0][0] + t[3][0] - t[1][0]),
            0.5 * (t[2][1] - t[0][1] + t[3][1] - t[1][1]),
        ];
        eu[0].hypot(eu[1]).max(ev[0].hypot(ev[1]))
    }

    #[inline]
    fn shade(&self, x: f64, y: f64, footprint: f64) -> [f32; 3] {
        let c = match self.look {
            Look::Solid(c) => c,
            Look::Tex {
                tex,
                wrap,
                scale,
                offset,
            } => tex.sample(
                x * scale[0] + offset[0],
                y * scale[1] + offset[1],
                footprint,
                wrap,
            ),
        };
        if self.gain == 1.0 {
            c
        } else {
            c.map(|v| v * self.gain)
        }
    }
}

/// One camera's view of the scene: surfaces in front-to-back priority (occluder, card,
/// wall); the nearest hit wins regardless.
struct Eye<'a> {
    cam: Intrinsics,
    surfaces: Vec<Surface<'a>>,
}

const MISS: u8 = u8::MAX;

impl<'a> Eye<'a> {
    fn new(
        cam: Intrinsics,
        cam_from_left: &Isometry3<f64>,
        left_from_model: &Isometry3<f64>,
        scene: &'a Scene,
        card_tex: &'a MipTexture,
        occ_tex: Option<&'a MipTexture>,
    ) -> Self {
        let mut surfaces = Vec::with_capacity(3);
        if let Some(o) = &scene.occluder {
            let [sx, sy] = o.size_mm;
            if sx > 0.0 && sy > 0.0 && sx.is_finite() && sy.is_finite() {
                let look = match (&o.fill, occ_tex) {
                    (OccluderFill::Texture(_), Some(t)) => Look::Tex {
                        tex: t,
                        wrap: Wrap::Clamp,
                        scale: [t.width() / sx, t.height() / sy],
                        offset: [0.5 * t.width(), 0.5 * t.height()],
                    },
                    (OccluderFill::Solid(c), _) => Look::Solid(c.map(f32::from)),
                    (OccluderFill::Texture(_), None) => Look::Solid([128.0; 3]),
                };
                surfaces.push(Surface {
                    plane: Plane::new(&(cam_from_left * o.left_from_occluder)),
                    half: Some([0.5 * sx, 0.5 * sy]),
                    look,
                    gain: 1.0,
                });
            }
        }
        let [l, b] = scene.card.size_mm;
        if l > 0.0 && b > 0.0 && l.is_finite() && b.is_finite() {
            let plane = Plane::new(&(cam_from_left * left_from_model));
            // The textured face looks along −z_M: visible iff the camera is on the −z side.
            let look = if plane.origin.z < 0.0 {
                Look::Tex {
                    tex: card_tex,
                    wrap: Wrap::Clamp,
                    scale: [card_tex.width() / l, card_tex.height() / b],
                    offset: [0.5 * card_tex.width(), 0.5 * card_tex.height()],
                }
            } else {
                Look::Solid(CARDBOARD.map(f32::from))
            };
            let gain = if scene.brightness.is_finite() && scene.brightness >= 0.0 {
                scene.brightness as f32
            } else {
                1.0
            };
            surfaces.push(Surface {
                plane,
                half: Some([0.5 * l, 0.5 * b]),
                look,
                gain,
            });
        }
        let bg = &scene.background;
        let mip = bg.mip();
        let wall = Isometry3::from_parts(
            Translation3::new(0.0, 0.0, bg.distance_mm()),
            UnitQuaternion::identity(),
        );
        surfaces.push(Surface {
            plane: Plane::new(&(cam_from_left * wall)),
            half: None,
            look: Look::Tex {
                tex: mip,
                wrap: Wrap::Mirror,
                scale: [1.0 / bg.texel_mm(), 1.0 / bg.texel_mm()],
                offset: [0.5 * mip.width(), 0.5 * mip.height()],
            },
            gain: 1.0,
        });
        Self { cam, surfaces }
    }

    /// Nearest surface hit by ray `d`: `(surface index, x, y)`.
    #[inline]
    fn trace(&self, d: &Vector3<f64>) -> Option<(usize, f64, f64)> {
        let mut best: Option<(usize, f64, f64, f64)> = None;
        for (k, s) in self.surfaces.iter().enumerate() {
            if let Some((lam, x, y)) = s.hit(d) {
                if best.is_none_or(|b| lam < b.1) {
                    best = Some((k, lam, x, y));
                }
            }
        }
        best.map(|(k, _, x, y)| (k, x, y))
    }

    fn corner_row(&self, v: f64, rays: &mut [Vector3<f64>], ids: &mut [u8]) {
        for (i, (r, id)) in rays.iter_mut().zip(ids.iter_mut()).enumerate() {
            *r = self.cam.ray(i as f64 - 0.5, v);
            *id = self.trace(r).map_or(MISS, |(k, _, _)| k as u8);
        }
    }

    /// Renders rows `y0..` of this eye into a side-by-side band.
    fn render_band(&self, chunk: &mut [u8], y0: usize, w: usize, eye: usize, sigma: f32, seed: u64) {
        let row_bytes = 2 * w * 3;
        let rows = chunk.len() / row_bytes;
        let mut top = vec![Vector3::zeros(); w + 1];
        let mut top_id = vec![MISS; w + 1];
        let mut bot = vec![Vector3::zeros(); w + 1];
        let mut bot_id = vec![MISS; w + 1];
        self.corner_row(y0 as f64 - 0.5, &mut top, &mut top_id);
        for r in 0..rows {
            let j = y0 + r;
            self.corner_row(j as f64 + 0.5, &mut bot, &mut bot_id);
            let row = &mut chunk[r * row_bytes + eye * w * 3..r * row_bytes + (eye + 1) * w * 3];
            let mut noise = Noise::new(seed, eye, j, sigma);
            for i in 0..w {
                let corners = [top[i], top[i + 1], bot[i], bot[i + 1]];
                let id = top_id[i];
                let c = if id == top_id[i + 1] && id == bot_id[i] && id == bot_id[i + 1] {
                    let d = self.cam.ray(i as f64, j as f64);
                    match self.trace(&d) {
                        Some((k, x, y)) => {
                            let s = &self.surfaces[k];
                            s.shade(x, y, s.footprint(&corners))
                        }
                        None => [0.0; 3],
                    }
                } else {
                    self.supersample(i, j, &corners)
                };
                let o = i * 3;
                for k in 0..3 {
                    let v = c[k] + noise.next();
                    row[o + k] = v.round().clamp(0.0, 255.0) as u8;
                }
            }
            std::mem::swap(&mut top, &mut bot);
            std::mem::swap(&mut top_id, &mut bot_id);
        }
    }

    /// 4×4 supersampling of an edge pixel.
    fn supersample(&self, i: usize, j: usize, corners: &[Vector3<f64>; 4]) -> [f32; 3] {
        const N: usize = 4;
        let mut footprints = [f64::NAN; 3];
        let mut acc = [0.0f32; 3];
        for b in 0..N {
            let v = j as f64 - 0.5 + (b as f64 + 0.5) / N as f64;
            for a in 0..N {
                let u = i as f64 - 0.5 + (a as f64 + 0.5) / N as f64;
                let d = self.cam.ray(u, v);
                if let Some((k, x, y)) = self.trace(&d) {
                    let s = &self.surfaces[k];
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

/// Seeded Gaussian noise for one row of one eye (independent of thread layout).
struct Noise {
    rng: Option<StdRng>,
    sigma: f32,
    spare: Option<f32>,
}

impl Noise {
    fn new(seed: u64, eye: usize, row: usize, sigma: f32) -> Self {
        let rng = (sigma > 0.0).then(|| {
            let key = seed
                .wrapping_mul(0x9e37_79b9_7f4a_7c15)
                .wrapping_add(((eye as u64) << 32) | row as u64);
            StdRng::seed_from_u64(splitmix(key))
        });
        Self {
            rng,
            sigma,
            spare: None,
        }
    }

    #[inline]
    fn next(&mut self) -> f32 {
        let Some(rng) = self.rng.as_mut() else {
            return 0.0;
        };
        if let Some(s) = self.spare.take() {
            return s;
        }
        // Box–Muller.
        let u1: f64 = 1.0 - rng.random::<f64>(); // (0, 1]
        let u2: f64 = rng.random::<f64>();
        let r = (-2.0 * u1.ln()).sqrt();
        let (s, c) = (std::f64::consts::TAU * u2).sin_cos();
        self.spare = Some((r * s) as f32 * self.sigma);
        (r * c) as f32 * self.sigma
    }
}

fn splitmix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests;
