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
mod eye;
mod noise;
mod rays;
pub mod scene;
mod surface;
mod texture;

use std::sync::Mutex;

use image::RgbImage;
use nalgebra::{Isometry3, Point3, Translation3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use crate::camera::{Intrinsics, StereoRig};
pub use crate::vision::frame::Region;
use eye::{Corner, Eye};
use texture::MipTexture;

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
        self.render_over(scene, out);
    }

    /// The frame of the scene without card and occluder.
    pub fn background(&self) -> &[u8] {
        &self.background
    }

    /// Renders the card and occluder of `scene` into `out`, which must already hold a
    /// copy of [`Renderer::background`] (a frame of another size is left alone).
    pub fn render_over(&mut self, scene: &Scene, out: &mut [u8]) {
        if out.len() != self.background.len() {
            return;
        }
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

#[cfg(test)]
mod tests;
