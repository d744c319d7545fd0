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
//! The exact rays through all pixel corners are computed once per camera and cached; rays
//! inside a pixel are bilinear blends of its corner rays (< 1e-3 px from exact).
//! Optional seeded Gaussian noise and card brightness complete the frame. Rows are rendered
//! in parallel bands; the output is side-by-side (left eye in the left half).

mod background;
mod rays;
pub mod scene;
mod texture;

use std::sync::{Arc, Mutex};

use image::RgbImage;
use nalgebra::{Isometry3, Matrix3, Point3, Translation3, UnitQuaternion, Vector3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use crate::camera::{Intrinsics, StereoRig};
pub use crate::vision::frame::Region;
use rays::RayTable;
use texture::{MipTexture, Wrap};

pub use background::Background;
pub use scene::{SceneError, SceneSpec};

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
    /// One colour, RGB 0–255.
    Solid([u8; 3]),
    /// Stretched over the whole rectangle (same mapping as the card).
    Texture(RgbImage),
}

/// An opaque rectangle (both faces alike) in the left-camera frame, centred on its local
/// origin, spanning its local x/y axes.
#[derive(Debug, Clone)]
pub struct Occluder {
    /// The occluder's local frame in the left-camera frame (translation in mm).
    pub left_from_occluder: Isometry3<f64>,
    /// Extent along local x and y, mm.
    pub size_mm: [f64; 2],
    /// What its faces look like.
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
        let valid = fraction > 0.0 && l > 0.0 && b > 0.0 && l.is_finite() && b.is_finite();
        if !valid {
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
            left_from_occluder: Isometry3::from_parts(Translation3::from(p.coords * s), left_from_model.rotation),
            size_mm: [size[0] * s, size[1] * s],
            fill,
        })
    }
}

/// Everything the synthetic camera sees.
#[derive(Debug, Clone)]
pub struct Scene {
    /// The target card.
    pub card: Card,
    /// The wall behind the card.
    pub background: Background,
    /// Standard deviation of additive Gaussian pixel noise, grey levels (0 = none).
    pub noise_sigma: f64,
    /// Multiplies the card's colour (1.0 = unchanged).
    pub brightness: f64,
    /// An opaque rectangle in view, if any (typically hiding part of the card).
    pub occluder: Option<Occluder>,
    /// Seed of the pixel noise.
    pub seed: u64,
}

/// Renders the side-by-side frame through the calibrated, distorted cameras.
pub fn render(rig: &StereoRig, left_from_hand: &Isometry3<f64>, scene: &Scene) -> RgbImage {
    let mut out = RgbImage::new(2 * rig.width, rig.height);
    render_into(rig, left_from_hand, scene, &mut out);
    out
}

/// [`render`] into an RGB8 buffer of `2·width × height` pixels (e.g. a loaned
/// shared-memory sample); a buffer of another size is left alone.
pub fn render_into(rig: &StereoRig, left_from_hand: &Isometry3<f64>, scene: &Scene, out: &mut [u8]) {
    let (w, h) = (rig.width as usize, rig.height as usize);
    let threads = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
    render_regions(
        rig,
        left_from_hand,
        scene,
        out,
        [Region::all(w, h), Region::all(w, h)],
        threads,
    );
}

/// Renders a moving card fast: the scene without card and occluder is rendered once,
/// and each frame copies it and re-renders only the pixels around the card and
/// occluder in each eye (on one thread, so a capture process leaves the other cores to
/// the estimator). Pixel noise is then static outside those regions. Textures and
/// scratch rows are kept, so a frame allocates nothing.
pub struct Renderer {
    rig: StereoRig,
    left_from_hand: Isometry3<f64>,
    background: Vec<u8>,
    textures: Textures,
    scratch: [Vec<Corner>; 2],
}

/// Extra pixels around a projected card or occluder (anti-aliased edges).
const REGION_MARGIN_PX: f64 = 3.0;

impl Renderer {
    /// Renders `scene` without card and occluder once, for `rig` with the hand frame at
    /// `left_from_hand` in the left-camera frame, and prepares the scene's textures.
    pub fn new(rig: &StereoRig, left_from_hand: &Isometry3<f64>, scene: &Scene) -> Self {
        let mut empty = scene.clone();
        empty.card.size_mm = [0.0, 0.0];
        empty.occluder = None;
        let mut background = vec![0u8; 2 * rig.width as usize * rig.height as usize * 3];
        render_into(rig, left_from_hand, &empty, &mut background);
        let corners = || Vec::with_capacity(rig.width as usize + 1);
        Self {
            rig: rig.clone(),
            left_from_hand: *left_from_hand,
            background,
            textures: Textures::new(scene),
            scratch: [corners(), corners()],
        }
    }

    /// Bytes of one side-by-side frame.
    pub fn frame_len(&self) -> usize {
        self.background.len()
    }

    /// Renders `scene` (the same scene as at construction, its card and occluder moved)
    /// into `out` ([`Renderer::frame_len`] bytes).
    pub fn render_into(&mut self, scene: &Scene, out: &mut [u8]) {
        if out.len() != self.background.len() {
            return;
        }
        out.copy_from_slice(&self.background);
        let left_from_model = self.left_from_hand * scene.card.hand_from_model;
        let card = (left_from_model, scene.card.size_mm);
        let occluder = scene.occluder.as_ref().map(|o| (o.left_from_occluder, o.size_mm));
        let (w, h) = (self.rig.width as usize, self.rig.height as usize);
        let eye = |cam_from_left: Isometry3<f64>, cam: &Intrinsics| {
            let seen = std::iter::once(card)
                .chain(occluder)
                .map(|(left_from_rect, size)| (cam_from_left * left_from_rect, size));
            Region::covering(cam, seen, w, h, |_| REGION_MARGIN_PX)
        };
        let regions = [
            eye(Isometry3::identity(), &self.rig.left),
            eye(self.rig.right_from_left, &self.rig.right),
        ];
        let eyes = eyes(&self.rig, &self.left_from_hand, scene, &self.textures);
        let [top, bot] = &mut self.scratch;
        let band = Band {
            y0: 0,
            w,
            sigma: noise_sigma(scene),
            seed: scene.seed,
        };
        for (e, eye) in eyes.iter().enumerate() {
            eye.render_band(out, &band, e, &regions[e], top, bot);
        }
    }
}

/// The card's and occluder's mip-mapped textures.
struct Textures {
    card: MipTexture,
    occluder: Option<MipTexture>,
}

impl Textures {
    fn new(scene: &Scene) -> Self {
        let occluder = match &scene.occluder {
            Some(Occluder {
                fill: OccluderFill::Texture(t),
                ..
            }) => Some(MipTexture::new(t)),
            _ => None,
        };
        Self {
            card: MipTexture::new(&scene.card.texture),
            occluder,
        }
    }
}

/// Both cameras' views of `scene`.
fn eyes<'a>(
    rig: &StereoRig,
    left_from_hand: &Isometry3<f64>,
    scene: &'a Scene,
    textures: &'a Textures,
) -> [Eye<'a>; 2] {
    let (w, h) = (rig.width as usize, rig.height as usize);
    let left_from_model = left_from_hand * scene.card.hand_from_model;
    [
        Eye::new(
            rig.left,
            w,
            h,
            &Isometry3::identity(),
            &left_from_model,
            scene,
            textures,
        ),
        Eye::new(rig.right, w, h, &rig.right_from_left, &left_from_model, scene, textures),
    ]
}

/// The noise level of `scene`, 0 when unset or invalid.
fn noise_sigma(scene: &Scene) -> f32 {
    if scene.noise_sigma.is_finite() && scene.noise_sigma > 0.0 {
        scene.noise_sigma as f32
    } else {
        0.0
    }
}

/// Rows `y0..` of the side-by-side frame being rendered (a band), frame width `w` per
/// eye, and the pixel noise.
struct Band {
    y0: usize,
    w: usize,
    sigma: f32,
    seed: u64,
}

/// Renders only `regions` (left, right) of the side-by-side frame in `out`, on up to
/// `threads` threads; other pixels are left as they are.
fn render_regions(
    rig: &StereoRig,
    left_from_hand: &Isometry3<f64>,
    scene: &Scene,
    out: &mut [u8],
    regions: [Region; 2],
    threads: usize,
) {
    let (w, h) = (rig.width as usize, rig.height as usize);
    if w == 0 || h == 0 || out.len() != 2 * w * h * 3 {
        return;
    }
    let textures = Textures::new(scene);
    let eyes = eyes(rig, left_from_hand, scene, &textures);
    let (sigma, seed) = (noise_sigma(scene), scene.seed);
    let threads = threads.clamp(1, 64);
    let band_rows = h.div_ceil(threads * 4).max(1);
    let row_bytes = 2 * w * 3;
    let work = Mutex::new(out.chunks_mut(row_bytes * band_rows).enumerate());
    std::thread::scope(|s| {
        for _ in 0..threads {
            s.spawn(|| {
                let (mut top, mut bot) = (Vec::new(), Vec::new());
                loop {
                    let next = match work.lock() {
                        Ok(mut it) => it.next(),
                        Err(_) => None,
                    };
                    let Some((band, chunk)) = next else { break };
                    let band = Band {
                        y0: band * band_rows,
                        w,
                        sigma,
                        seed,
                    };
                    for (e, eye) in eyes.iter().enumerate() {
                        eye.render_band(chunk, &band, e, &regions[e], &mut top, &mut bot);
                    }
                }
            });
        }
    });
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
        Some((lam, self.origin.x + lam * dm.x, self.origin.y + lam * dm.y))
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
    fn footprint_xy(&self, xy: &[[f64; 2]; 4]) -> f64 {
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
    fn shade(&self, x: f64, y: f64, footprint: f64) -> [f32; 3] {
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

/// One camera's view of the scene: surfaces in front-to-back priority (occluder, card,
/// wall); the nearest hit wins regardless.
struct Eye<'a> {
    rays: Arc<RayTable>,
    /// Occluder, card, wall: the first `n` are set.
    surfaces: [Option<Surface<'a>>; 3],
}

const MISS: u8 = u8::MAX;

/// A pixel corner: its ray, the surface it hits (`MISS` = none) and the hit point there.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Corner {
    ray: Vector3<f64>,
    id: u8,
    xy: [f64; 2],
}

impl<'a> Eye<'a> {
    fn new(
        cam: Intrinsics,
        w: usize,
        h: usize,
        cam_from_left: &Isometry3<f64>,
        left_from_model: &Isometry3<f64>,
        scene: &'a Scene,
        textures: &'a Textures,
    ) -> Self {
        let (card_tex, occ_tex) = (&textures.card, textures.occluder.as_ref());
        let mut surfaces = [None, None, None];
        let mut n = 0;
        let mut push = |s: Surface<'a>| {
            surfaces[n] = Some(s);
            n += 1;
        };
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
                push(Surface {
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
            push(Surface {
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
        push(Surface {
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
        Self {
            rays: rays::table(&cam, w, h),
            surfaces,
        }
    }

    fn surface(&self, k: usize) -> Option<&Surface<'a>> {
        self.surfaces.get(k).and_then(Option::as_ref)
    }

    /// Nearest surface hit by ray `d`: `(surface index, x, y)`.
    #[inline]
    fn trace(&self, d: &Vector3<f64>) -> Option<(usize, f64, f64)> {
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
    fn corner_row(&self, jc: usize, row: &mut [Corner], i0: usize) {
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
    fn render_band(
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
    fn supersample(&self, corners: &[Vector3<f64>; 4]) -> [f32; 3] {
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
fn blend(c: &[Vector3<f64>; 4], fu: f64, fv: f64) -> Vector3<f64> {
    let top = c[0] + (c[1] - c[0]) * fu;
    let bot = c[2] + (c[3] - c[2]) * fu;
    top + (bot - top) * fv
}

/// Rounds and saturates a colour value.
#[inline]
fn to_u8(v: f32) -> u8 {
    // `as` truncates towards zero; the value is non-negative after the clamp.
    (v.clamp(0.0, 255.0) + 0.5) as u8
}

/// Seeded Gaussian noise for one row of one eye (independent of thread layout): standard
/// normal quantiles at 2^16 equally likely levels, picked by the row's random stream.
struct Noise {
    rng: Option<StdRng>,
    sigma: f32,
    table: &'static [f32],
}

const NOISE_LEVELS: usize = 1 << 16;

fn normal_table() -> &'static [f32] {
    static TABLE: std::sync::OnceLock<Vec<f32>> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        (0..NOISE_LEVELS)
            .map(|k| normal_quantile((k as f64 + 0.5) / NOISE_LEVELS as f64) as f32)
            .collect()
    })
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
            table: if sigma > 0.0 { normal_table() } else { &[] },
        }
    }

    #[inline]
    fn next(&mut self) -> f32 {
        match self.rng.as_mut() {
            Some(rng) => self.table[(rng.random::<u32>() >> 16) as usize] * self.sigma,
            None => 0.0,
        }
    }
}

/// Inverse standard normal CDF (Acklam's rational approximation, relative error < 1.2e-9).
fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969_683_028_665_376e1,
        2.209_460_984_245_205e2,
        -2.759_285_104_469_687e2,
        1.383_577_518_672_69e2,
        -3.066_479_806_614_716e1,
        2.506_628_277_459_239,
    ];
    const B: [f64; 5] = [
        -5.447_609_879_822_406e1,
        1.615_858_368_580_409e2,
        -1.556_989_798_598_866e2,
        6.680_131_188_771_972e1,
        -1.328_068_155_288_572e1,
    ];
    const C: [f64; 6] = [
        -7.784_894_002_430_293e-3,
        -3.223_964_580_411_365e-1,
        -2.400_758_277_161_838,
        -2.549_732_539_343_734,
        4.374_664_141_464_968,
        2.938_163_982_698_783,
    ];
    const D: [f64; 4] = [
        7.784_695_709_041_462e-3,
        3.224_671_290_700_398e-1,
        2.445_134_137_142_996,
        3.754_408_661_907_416,
    ];
    const P_LOW: f64 = 0.02425;
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    if p < P_LOW {
        tail((-2.0 * p.ln()).sqrt())
    } else if p > 1.0 - P_LOW {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
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
