//! The background wall: a textured plane facing the left camera at a fixed distance.
//!
//! The wall is the plane `z = distance_mm` of the left-camera frame; its texture is centred
//! on the optical axis, `texel_mm` millimetres per texel, and mirror-repeated beyond its
//! edges so that any field of view is covered without holes.

use image::{Rgb, RgbImage};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use super::texture::{MipTexture, Wrap};

/// Half field of view (as tangent) the collage texture covers, horizontally / vertically.
/// Covers the ZED 2i at every resolution; anything wider sees the mirrored texture.
const HALF_TAN_X: f64 = 1.5;
const HALF_TAN_Y: f64 = 0.95;
/// Extra wall around the field of view on each side (stereo baseline, off-axis cards).
const MARGIN_MM: f64 = 200.0;
/// Angular resolution of the collage: texels per radian near the optical axis.
const TEXELS_PER_RAD: f64 = 800.0;
/// Size caps of the collage texture.
const MAX_W: f64 = 3000.0;
const MAX_H: f64 = 2000.0;

/// A textured wall facing the camera (plane `z = distance_mm` in the left-camera frame).
#[derive(Debug, Clone)]
pub struct Background {
    distance_mm: f64,
    texel_mm: f64,
    mip: MipTexture,
}

impl Background {
    /// A cluttered, colourful, real-looking wall: a collage of the given photos at random
    /// scales/positions/overlaps (deterministic for a seed), filling a texture that covers the whole field of view at that distance, plus mild lighting gradient.
    ///
    /// The photos are pinned up like prints (white border, small random tilt, random
    /// mirroring); an empty `photos` slice yields procedural posters instead.
    pub fn collage(photos: &[RgbImage], seed: u64, distance_mm: f64) -> Background {
        let d = if distance_mm.is_finite() && distance_mm > 1.0 {
            distance_mm
        } else {
            1.0
        };
        let width_mm = 2.0 * HALF_TAN_X * d + 2.0 * MARGIN_MM;
        let height_mm = 2.0 * HALF_TAN_Y * d + 2.0 * MARGIN_MM;
        let texel_mm = (d / TEXELS_PER_RAD).max(width_mm / MAX_W).max(height_mm / MAX_H);
        let w = (width_mm / texel_mm).ceil().max(1.0) as u32;
        let h = (height_mm / texel_mm).ceil().max(1.0) as u32;
        let mut rng = StdRng::seed_from_u64(seed ^ 0x6261_636b_6772_6f75);

        let usable: Vec<&RgbImage> = photos.iter().filter(|p| p.width() > 0 && p.height() > 0).collect();
        let procedural: Vec<RgbImage>;
        let sources: Vec<&RgbImage> = if usable.is_empty() {
            procedural = (0..6).map(|_| procedural_poster(&mut rng)).collect();
            procedural.iter().collect()
        } else {
            usable
        };
        let textures: Vec<MipTexture> = sources.iter().map(|p| MipTexture::new(p)).collect();
        let posters = plan_posters(&sources, w as f64, h as f64, d / texel_mm, &mut rng);
        let light = Lighting {
            gx: rng.random_range(-0.2..0.2),
            gy: rng.random_range(-0.2..0.2),
            vignette: rng.random_range(0.1..0.25),
        };
        let base = mean_colour(&sources);

        let mut canvas = RgbImage::new(w, h);
        let row_bytes = w as usize * 3;
        let threads = std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1)
            .clamp(1, 16);
        let band_rows = (h as usize).div_ceil(threads).max(1);
        std::thread::scope(|s| {
            for (band, chunk) in canvas.chunks_mut(row_bytes * band_rows).enumerate() {
                let (posters, textures, light) = (&posters, &textures, &light);
                s.spawn(move || {
                    let y0 = band * band_rows;
                    draw_band(chunk, y0, w, h, base, posters, textures, light);
                });
            }
        });

        Background {
            distance_mm,
            texel_mm,
            mip: MipTexture::new(&canvas),
        }
    }

    /// A wall showing `texture` centred on the optical axis, `texel_mm` mm per texel,
    /// mirror-repeated beyond its edges.
    pub fn from_texture(texture: &RgbImage, distance_mm: f64, texel_mm: f64) -> Background {
        let texel_mm = if texel_mm.is_finite() && texel_mm > 0.0 {
            texel_mm
        } else {
            1.0
        };
        Background {
            distance_mm,
            texel_mm,
            mip: MipTexture::new(texture),
        }
    }

    /// A uniformly coloured wall (tests).
    pub fn solid(colour: [u8; 3], distance_mm: f64) -> Background {
        Background::from_texture(&RgbImage::from_pixel(1, 1, Rgb(colour)), distance_mm, 1.0)
    }

    /// Distance of the wall from the left camera along its optical axis, mm.
    pub fn distance_mm(&self) -> f64 {
        self.distance_mm
    }

    /// Wall millimetres per texture texel.
    pub fn texel_mm(&self) -> f64 {
        self.texel_mm
    }

    /// Texture size in texels `(width, height)`.
    pub fn texture_size(&self) -> (u32, u32) {
        (self.mip.width() as u32, self.mip.height() as u32)
    }

    /// The mip-mapped wall texture (renderer).
    pub(crate) fn mip(&self) -> &MipTexture {
        &self.mip
    }

    /// Colour of the wall at wall coordinates `(x, y)` mm (left-camera x/y), for a
    /// footprint of `footprint_mm`.
    #[cfg(test)]
    pub(crate) fn sample(&self, x: f64, y: f64, footprint_mm: f64) -> [f32; 3] {
        let u = x / self.texel_mm + 0.5 * self.mip.width();
        let v = y / self.texel_mm + 0.5 * self.mip.height();
        self.mip.sample(u, v, footprint_mm / self.texel_mm, Wrap::Mirror)
    }
}

/// One photo (or a crop of it) pinned to the wall; lengths in canvas texels.
struct Poster {
    src: usize,
    /// Crop of the source photo: top-left and size, photo texels.
    crop: [f64; 4],
    cx: f64,
    cy: f64,
    cos: f64,
    sin: f64,
    /// Canvas texels per photo texel.
    scale: f64,
    flip: bool,
    half_w: f64,
    half_h: f64,
    border: f64,
    paper: [u8; 3],
    /// Bounding box (inclusive start, exclusive end).
    x0: usize,
    x1: usize,
    y0: usize,
    y1: usize,
}

impl Poster {
    /// Canvas point `(x, y)` in poster coordinates (centre origin, unrotated).
    #[inline]
    fn local(&self, x: f64, y: f64) -> (f64, f64) {
        let (qx, qy) = (x - self.cx, y - self.cy);
        (self.cos * qx + self.sin * qy, -self.sin * qx + self.cos * qy)
    }
}

struct Lighting {
    gx: f64,
    gy: f64,
    vignette: f64,
}

/// Places posters in random order at not yet covered spots of a coarse grid until every
/// grid point is covered, then some more anywhere on top (clutter). Poster sizes are
/// log-uniform, their shorter side 8–35 % of the wall distance (`d_tex`, in texels).
fn plan_posters(sources: &[&RgbImage], w: f64, h: f64, d_tex: f64, rng: &mut StdRng) -> Vec<Poster> {
    let cell = (0.03 * d_tex).max(2.0);
    let cols = (w / cell).ceil().max(1.0) as usize;
    let rows = (h / cell).ceil().max(1.0) as usize;
    let mut covered = vec![false; cols * rows];
    let mut order: Vec<usize> = (0..cols * rows).collect();
    // Fisher–Yates shuffle: random stacking order.
    for i in (1..order.len()).rev() {
        let j = rng.random_range(0..=i);
        order.swap(i, j);
    }
    let mut posters = Vec::new();
    for idx in order {
        if covered[idx] {
            continue;
        }
        let (c, r) = (idx % cols, idx / cols);
        let cx = (c as f64 + rng.random_range(0.0..1.0)) * cell;
        let cy = (r as f64 + rng.random_range(0.0..1.0)) * cell;
        let p = poster(sources, cx, cy, w, h, d_tex, rng);
        // Mark the grid points the poster covers (always including its own cell).
        covered[idx] = true;
        let (c0, c1) = ((p.x0 as f64 / cell) as usize, (p.x1 as f64 / cell) as usize + 1);
        let (r0, r1) = ((p.y0 as f64 / cell) as usize, (p.y1 as f64 / cell) as usize + 1);
        for rr in r0..r1.min(rows) {
            for cc in c0..c1.min(cols) {
                let (lx, ly) = p.local((cc as f64 + 0.5) * cell, (rr as f64 + 0.5) * cell);
                if lx.abs() <= p.half_w + p.border && ly.abs() <= p.half_h + p.border {
                    covered[rr * cols + cc] = true;
                }
            }
        }
        posters.push(p);
    }
    for _ in 0..posters.len() / 4 {
        let (cx, cy) = (rng.random_range(0.0..w), rng.random_range(0.0..h));
        posters.push(poster(sources, cx, cy, w, h, d_tex, rng));
    }
    posters
}

/// A random poster centred at `(cx, cy)`.
fn poster(sources: &[&RgbImage], cx: f64, cy: f64, w: f64, h: f64, d_tex: f64, rng: &mut StdRng) -> Poster {
    let src = rng.random_range(0..sources.len());
    let (pw, ph) = (sources[src].width() as f64, sources[src].height() as f64);
    // A random crop of 50–100 % of each side (varies content and aspect).
    let cw = pw * rng.random_range(0.5..=1.0);
    let ch = ph * rng.random_range(0.5..=1.0);
    let crop = [rng.random_range(0.0..=pw - cw), rng.random_range(0.0..=ph - ch), cw, ch];
    let min_side = d_tex * rng.random_range(0.08f64.ln()..0.35f64.ln()).exp();
    let scale = min_side / cw.min(ch);
    let angle = rng.random_range(-8.0f64..8.0).to_radians();
    let (sin, cos) = angle.sin_cos();
    let half_w = 0.5 * cw * scale;
    let half_h = 0.5 * ch * scale;
    let border = if rng.random::<f64>() < 0.6 {
        rng.random_range(0.02..0.06) * min_side
    } else {
        0.0
    };
    let grey = rng.random_range(215u8..=245);
    let paper = [grey, grey, grey.saturating_sub(rng.random_range(0..12))];
    let ext_x = half_w + border;
    let ext_y = half_h + border;
    let bx = ext_x * cos.abs() + ext_y * sin.abs();
    let by = ext_x * sin.abs() + ext_y * cos.abs();
    let clampi = |v: f64, hi: f64| v.clamp(0.0, hi) as usize;
    Poster {
        src,
        crop,
        cx,
        cy,
        cos,
        sin,
        scale,
        flip: rng.random::<f64>() < 0.3,
        half_w,
        half_h,
        border,
        paper,
        x0: clampi((cx - bx).floor(), w),
        x1: clampi((cx + bx).ceil() + 1.0, w),
        y0: clampi((cy - by).floor(), h),
        y1: clampi((cy + by).ceil() + 1.0, h),
    }
}

/// Draws rows `y0..` of the canvas: posters front to back (each texel is sampled once),
/// the board colour where none lands, then the lighting.
#[allow(clippy::too_many_arguments)]
fn draw_band(
    chunk: &mut [u8],
    y0: usize,
    w: u32,
    h: u32,
    base: [u8; 3],
    posters: &[Poster],
    textures: &[MipTexture],
    light: &Lighting,
) {
    let w = w as usize;
    let rows = chunk.len() / (w * 3);
    let mut done = vec![false; w * rows];
    for p in posters.iter().rev() {
        let tex = &textures[p.src];
        // Baked once: the nearest power-of-two mip level is plenty.
        let footprint = (1.0 / p.scale).log2().round().exp2();
        let ys = p.y0.max(y0);
        let ye = p.y1.min(y0 + rows);
        let [sx, sy, cw, ch] = p.crop;
        for y in ys..ye {
            let r = y - y0;
            for x in p.x0..p.x1 {
                if done[r * w + x] {
                    continue;
                }
                let (lx, ly) = p.local(x as f64 + 0.5, y as f64 + 0.5);
                if lx.abs() > p.half_w + p.border || ly.abs() > p.half_h + p.border {
                    continue;
                }
                done[r * w + x] = true;
                let o = (r * w + x) * 3;
                if lx.abs() > p.half_w || ly.abs() > p.half_h {
                    chunk[o..o + 3].copy_from_slice(&p.paper);
                    continue;
                }
                let mut u = lx / p.scale + 0.5 * cw;
                if p.flip {
                    u = cw - u;
                }
                let v = ly / p.scale + 0.5 * ch;
                let c = tex.sample(sx + u, sy + v, footprint, Wrap::Clamp);
                for k in 0..3 {
                    chunk[o + k] = (c[k].clamp(0.0, 255.0) + 0.5) as u8;
                }
            }
        }
    }
    for (px, &d) in chunk.chunks_exact_mut(3).zip(&done) {
        if !d {
            px.copy_from_slice(&base);
        }
    }
    let (wf, hf) = (w as f64, h as f64);
    for r in 0..rows {
        let ny = (y0 + r) as f64 / hf - 0.5;
        for x in 0..w {
            let nx = x as f64 / wf - 0.5;
            let f = 1.0 + light.gx * nx + light.gy * ny - 2.0 * light.vignette * (nx * nx + ny * ny);
            let o = (r * w + x) * 3;
            for k in 0..3 {
                chunk[o + k] = (chunk[o + k] as f64 * f).clamp(0.0, 255.0).round() as u8;
            }
        }
    }
}

fn mean_colour(sources: &[&RgbImage]) -> [u8; 3] {
    let mut sum = [0.0f64; 3];
    let mut n = 0.0;
    for img in sources {
        for p in img.pixels().step_by(7) {
            for (s, &c) in sum.iter_mut().zip(&p.0) {
                *s += c as f64;
            }
            n += 1.0;
        }
    }
    if n == 0.0 {
        return [120, 115, 105];
    }
    sum.map(|s| (0.7 * s / n).round().clamp(0.0, 255.0) as u8)
}

/// A colourful synthetic poster (stripes, blobs and a gradient) for photo-less walls.
fn procedural_poster(rng: &mut StdRng) -> RgbImage {
    let mut col = || -> [f64; 3] {
        [
            rng.random_range(30.0..230.0),
            rng.random_range(30.0..230.0),
            rng.random_range(30.0..230.0),
        ]
    };
    let (a, b, c) = (col(), col(), col());
    let period = rng.random_range(12.0..48.0);
    let angle: f64 = rng.random_range(0.0..std::f64::consts::PI);
    let (bx, by, br) = (
        rng.random_range(40.0..216.0),
        rng.random_range(40.0..216.0),
        rng.random_range(20.0..70.0),
    );
    RgbImage::from_fn(256, 256, |x, y| {
        let (x, y) = (x as f64, y as f64);
        let t = y / 255.0;
        let s = ((x * angle.cos() + y * angle.sin()) / period).floor() as i64 % 2 == 0;
        let mut p = [0.0; 3];
        for k in 0..3 {
            p[k] = a[k] * (1.0 - t) + b[k] * t;
            if s {
                p[k] *= 0.75;
            }
        }
        if (x - bx).hypot(y - by) < br {
            p = c;
        }
        Rgb(p.map(|v| v.round().clamp(0.0, 255.0) as u8))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn photos() -> Vec<RgbImage> {
        vec![
            RgbImage::from_fn(64, 48, |x, y| Rgb([(x * 4) as u8, (y * 5) as u8, 90])),
            RgbImage::from_fn(40, 60, |x, _| Rgb([200, (x * 6) as u8, 30])),
        ]
    }

    #[test]
    fn collage_is_deterministic_and_seed_dependent() {
        let a = Background::collage(&photos(), 3, 1500.0);
        let b = Background::collage(&photos(), 3, 1500.0);
        let c = Background::collage(&photos(), 4, 1500.0);
        assert_eq!(a.texture_size(), b.texture_size());
        let probe = |bg: &Background| -> Vec<[f32; 3]> {
            (0..50)
                .map(|i| bg.sample(i as f64 * 37.0 - 900.0, i as f64 * 11.0 - 300.0, 1.0))
                .collect()
        };
        assert_eq!(probe(&a), probe(&b));
        assert_ne!(probe(&a), probe(&c));
    }

    #[test]
    fn collage_covers_field_of_view_and_handles_odd_input() {
        let bg = Background::collage(&photos(), 1, 1000.0);
        let (w, h) = bg.texture_size();
        assert!(w as f64 * bg.texel_mm() >= 2.0 * HALF_TAN_X * 1000.0);
        assert!(h as f64 * bg.texel_mm() >= 2.0 * HALF_TAN_Y * 1000.0);
        // No photos, bad distances: still a wall, no panic.
        let p = Background::collage(&[], 1, 1000.0);
        assert!(p.texture_size().0 > 100);
        let _ = Background::collage(&[RgbImage::new(0, 0)], 1, f64::NAN);
        let _ = Background::collage(&photos(), 1, -5.0);
    }
}
