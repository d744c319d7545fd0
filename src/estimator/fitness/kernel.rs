//! The hot loop: where each sample point lands and what it sees there.
//!
//! Points go through in chunks, three passes each, all but the second written so the
//! compiler vectorises them: project the chunk through the camera model (pose, pinhole,
//! Brown–Conrady distortion, in `f32`) to pixel indices, read the texels, count the
//! matches. No branch depends on the image: a point off the image is clamped onto the
//! ring of outside texels around it (see [`crate::vision::lookup`]). On x86-64 CPUs with AVX2
//! the same code is compiled a second time for 8-wide vectors and chosen at run time.

use std::mem::MaybeUninit;

use nalgebra::Vector3;

use super::PointSet;
use crate::camera::Intrinsics;
use crate::vision::lookup::{LookupImage, OUTSIDE};
use crate::vision::simd::avx2_multiversion;

/// Where a model point (photo pixels) lands in one camera for one candidate: the
/// camera-frame axes and origin of the model (`[ax | ay | t]`, row-major) and the
/// camera's intrinsics, all in `f32`.
#[derive(Debug, Clone, Copy)]
pub struct Projection {
    m: [f32; 9],
    fx: f32,
    fy: f32,
    /// Principal point in padded texel coordinates of the lookup region.
    cx: f32,
    cy: f32,
    k: [f32; 5],
}

/// Points per chunk: the index buffer stays in L1 and on the stack.
const CHUNK: usize = 256;
/// Adding 2²³ to a float in `[0, 2²³)` leaves its nearest integer in the mantissa bits.
const ROUND: f32 = 8_388_608.0;
/// Smallest depth in front of the camera that counts as visible, mm.
const MIN_DEPTH: f32 = 1e-3;

/// The projection of a model placed at `t` with axes `ax`, `ay` (mm per photo pixel, in
/// the camera's frame) through `cam` onto a padded lookup image whose region starts at
/// image pixel `origin`.
pub fn projection(cam: &Intrinsics, origin: (usize, usize), [ax, ay, t]: [&Vector3<f64>; 3]) -> Projection {
    let mut m = [0.0f32; 9];
    for (col, v) in [ax, ay, t].into_iter().enumerate() {
        for row in 0..3 {
            m[3 * row + col] = v[row] as f32;
        }
    }
    Projection {
        m,
        fx: cam.fx as f32,
        fy: cam.fy as f32,
        cx: (cam.cx + 1.0 - origin.0 as f64) as f32,
        cy: (cam.cy + 1.0 - origin.1 as f64) as f32,
        k: [cam.k1, cam.k2, cam.p1, cam.p2, cam.k3].map(|k| k as f32),
    }
}

/// Padded-image coordinates of a model point, `(0, 0)` (the outside ring) behind the
/// camera.
#[inline(always)]
pub(super) fn pixel(p: &Projection, x: f32, y: f32) -> (f32, f32) {
    let (m, [k1, k2, p1, p2, k3]) = (&p.m, p.k);
    let z = m[6] * x + m[7] * y + m[8];
    let inv = 1.0 / z;
    let xn = (m[0] * x + m[1] * y + m[2]) * inv;
    let yn = (m[3] * x + m[4] * y + m[5]) * inv;
    let r2 = xn * xn + yn * yn;
    let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
    let xd = xn * radial + 2.0 * p1 * xn * yn + p2 * (r2 + 2.0 * xn * xn);
    let yd = yn * radial + p1 * (r2 + 2.0 * yn * yn) + 2.0 * p2 * xn * yn;
    if z > MIN_DEPTH {
        (p.fx * xd + p.cx, p.fy * yd + p.cy)
    } else {
        (0.0, 0.0)
    }
}

/// Index buffers of one chunk, left uninitialised (evaluating a coarse thumbnail of a
/// few hundred points would otherwise spend a tenth of its time clearing them).
struct Chunk {
    idx: [MaybeUninit<u32>; CHUNK],
    /// Texels widened to `u32`: the matching loops run on 32-bit lanes.
    tex: [MaybeUninit<u32>; CHUNK],
}

impl Chunk {
    fn new() -> Self {
        Self {
            idx: [MaybeUninit::uninit(); CHUNK],
            tex: [MaybeUninit::uninit(); CHUNK],
        }
    }

    /// The texels under points `(xs[i], ys[i])` (the first [`CHUNK`] of them): nearest
    /// pixel, or the outside ring for points off the image or behind the camera.
    #[inline(always)]
    fn read(&mut self, img: &LookupImage, p: &Projection, xs: &[f32], ys: &[f32]) -> &[u32] {
        let n = xs.len().min(ys.len()).min(CHUNK);
        let (u_max, v_max) = ((img.width - 1) as f32, (img.height - 1) as f32);
        let width = img.width as f32;
        // A local copy keeps the loop free of loads the compiler cannot hoist.
        let p = *p;
        for ((&x, &y), o) in xs[..n].iter().zip(&ys[..n]).zip(self.idx.iter_mut()) {
            let (u, v) = pixel(&p, x, y);
            // `max` first: it turns NaN into 0.
            let ur = (u.max(0.0).min(u_max) + ROUND) - ROUND;
            let vr = (v.max(0.0).min(v_max) + ROUND) - ROUND;
            o.write((vr * width + ur + ROUND).to_bits().wrapping_sub(ROUND.to_bits()));
        }
        // SAFETY: the loop above wrote the first `n` indices.
        let idx: &[u32] = unsafe { std::slice::from_raw_parts(self.idx.as_ptr().cast(), n) };
        let px = &img.px[..img.width * img.height];
        for (t, &i) in self.tex.iter_mut().zip(idx) {
            // SAFETY: `i = v·width + u` with `u ≤ width − 1` and `v ≤ height − 1` (clamped
            // above, exact in f32 below `MAX_TEXELS`), so `i < width · height = px.len()`.
            t.write(unsafe { *px.get_unchecked(i as usize) } as u32);
        }
        // SAFETY: the loop above wrote the first `n` texels.
        unsafe { std::slice::from_raw_parts(self.tex.as_ptr().cast(), n) }
    }

    /// The pixel index of point `k` of the last [`Chunk::read`] (`k` below its length).
    #[cfg(test)]
    fn index(&self, k: usize) -> u32 {
        // SAFETY: tests ask only for points the last read wrote.
        unsafe { self.idx[k].assume_init() }
    }
}

/// Colour tolerances: a model point against its pixel, and the left pixel against the
/// right one; and the outer points' test.
#[derive(Debug, Clone, Copy)]
pub struct Tolerances {
    /// Largest hue gap of a chromatic match (OpenCV hue units).
    pub hue: u8,
    /// Largest saturation gap of a chromatic match.
    pub sat: u8,
    /// Largest left–right hue gap of a confirmed point.
    pub stereo_hue: u8,
    /// Largest left–right saturation gap of a confirmed point.
    pub stereo_sat: u8,
    /// The outer points' test.
    pub outer: OuterTest,
}

/// Eq. 16's test of an outer point: does its pixel look like the target (`e4`)?
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OuterTest {
    /// The paper's test on the raw hue (the texels' second byte) instead of robust
    /// mode's colour-class test.
    pub raw_hue: bool,
    /// `H̄_in` as an OpenCV hue.
    pub mean_hue: u8,
    /// The hue threshold around `mean_hue`.
    pub threshold: u8,
    /// The central rectangle's colour code: a chromatic centre matches a chromatic
    /// pixel of near hue and saturation, an achromatic one a pixel of its class.
    pub center_code: u8,
    /// The central rectangle's mean saturation.
    pub center_sat: u8,
    /// Largest saturation gap of a pixel that matches a chromatic centre.
    pub sat_tolerance: u8,
}

/// How many of `hits` are true. Counts here never exceed the model's point count, so
/// the sums are wrapping: a checked `+` (overflow checks in tests) would keep these
/// loops from vectorising.
#[inline(always)]
fn count_true(hits: impl Iterator<Item = bool>) -> u32 {
    hits.fold(0u32, |n, hit| n.wrapping_add(hit as u32))
}

impl OuterTest {
    /// How many of `texels` see the target (a point off the image always does: a
    /// mismatch). The test's branch is taken once, each loop is branch-free vector code.
    #[inline(always)]
    fn targets(&self, texels: &[u32]) -> u32 {
        if self.raw_hue {
            count_true(texels.iter().map(|&t| self.raw_target(t)))
        } else if self.center_code < 180 {
            count_true(texels.iter().map(|&t| self.chromatic_target(t)))
        } else {
            count_true(texels.iter().map(|&t| self.class_target(t)))
        }
    }

    #[inline(always)]
    fn near(&self, hue: u32) -> bool {
        hue_gap(hue, self.mean_hue as u32) < self.threshold as u32
    }

    /// The paper: the raw hue near `H̄_in`.
    #[inline(always)]
    fn raw_target(&self, t: u32) -> bool {
        ((t & 0xff) == OUTSIDE as u32) | self.near(t >> 8)
    }

    /// A chromatic centre: a chromatic pixel of near hue and saturation.
    #[inline(always)]
    fn chromatic_target(&self, t: u32) -> bool {
        let (code, sat) = (t & 0xff, t >> 8);
        (code == OUTSIDE as u32)
            | ((code < 180) & self.near(code) & (sat.abs_diff(self.center_sat as u32) <= self.sat_tolerance as u32))
    }

    /// An achromatic centre: a pixel of its class.
    #[inline(always)]
    fn class_target(&self, t: u32) -> bool {
        let code = t & 0xff;
        (code == OUTSIDE as u32) | (code == self.center_code as u32)
    }
}

/// What one candidate's points see in both images.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Counts {
    /// Inner points whose colour matches (Fig. 8 / Table 1), left and right.
    pub close: [u32; 2],
    /// Outer points that see background (eq. 16), left and right.
    pub background: [u32; 2],
    /// Inner points that match in the left image and whose right pixel shows the same
    /// colour (chromatic: hues within `stereo_hue`, saturations within `stereo_sat`;
    /// achromatic: the same class): both views confirm the same surface point, as they
    /// do where depth and tilt are right.
    pub confirmed: u32,
    /// Inner points that land on the image (not off it or behind the camera), left and
    /// right.
    pub inner_seen: [u32; 2],
    /// Outer points that land on the image, left and right.
    pub outer_seen: [u32; 2],
}

/// Whether a texel is on the image (not the outside ring).
#[inline(always)]
fn on_image(t: u32) -> bool {
    (t & 0xff) != OUTSIDE as u32
}

/// Circular distance of two hues (0–180); callers check that codes are chromatic.
#[inline(always)]
fn hue_gap(a: u32, b: u32) -> u32 {
    let d = a.abs_diff(b).min(180);
    (180 - d).min(d)
}

/// Fig. 8 for a chromatic model colour: a chromatic pixel of close hue and saturation.
#[inline(always)]
fn chromatic_match(t: u32, code: u8, sat: u8, tol: &Tolerances) -> bool {
    let (t_code, t_sat) = (t & 0xff, t >> 8);
    (t_code < 180) & (hue_gap(t_code, code as u32) <= tol.hue as u32) & (t_sat.abs_diff(sat as u32) <= tol.sat as u32)
}

/// Left and right pixels show the same colour (see [`Counts::confirmed`]).
#[inline(always)]
fn same_colour(l: u32, r: u32, tol: &Tolerances) -> bool {
    let (lc, rc) = (l & 0xff, r & 0xff);
    let (ls, rs) = (l >> 8, r >> 8);
    (hue_gap(lc, rc) <= tol.stereo_hue as u32) & (ls.abs_diff(rs) <= tol.stereo_sat as u32)
}

/// [`Counts`] in the left image alone (the left-only scan): the right image and
/// projection are not read, their counts and `confirmed` are 0. With `seen`, the points
/// on the image are counted too (otherwise those counts are 0).
pub fn count_left(points: &PointSet, img: &LookupImage, p: &Projection, tol: &Tolerances, seen: bool) -> Counts {
    if seen {
        dispatch::<false, true>(points, [img, img], [p, p], tol)
    } else {
        dispatch::<false, false>(points, [img, img], [p, p], tol)
    }
}

/// [`Counts`] of one candidate, projected by `projections` into `images` (left, right);
/// with `seen`, the points on each image are counted too (otherwise those counts are 0).
pub fn count(
    points: &PointSet,
    images: [&LookupImage; 2],
    projections: [&Projection; 2],
    tol: &Tolerances,
    seen: bool,
) -> Counts {
    if seen {
        dispatch::<true, true>(points, images, projections, tol)
    } else {
        dispatch::<true, false>(points, images, projections, tol)
    }
}

/// Whether every point within `reach` (photo pixels from the box centre, each way) of
/// the model lands on `img` by projection `p`, at least `margin` texels inside its
/// edge: the projections of the reach's four corners do (the model is flat, and lens
/// distortion bends its edges by less than the margin).
pub fn wholly_on(img: &LookupImage, p: &Projection, [rx, ry]: [f32; 2], margin: f32) -> bool {
    let (lo, hi_u, hi_v) = (
        1.0 + margin,
        (img.width - 2) as f32 - margin,
        (img.height - 2) as f32 - margin,
    );
    [(-rx, -ry), (rx, -ry), (-rx, ry), (rx, ry)].into_iter().all(|(x, y)| {
        let (u, v) = pixel(p, x, y);
        (lo..=hi_u).contains(&u) && (lo..=hi_v).contains(&v)
    })
}

avx2_multiversion! {
    /// [`count_chunks`], with AVX2 where the CPU has it.
    fn dispatch<const BOTH: bool, const SEEN: bool>(
        points: &PointSet,
        images: [&LookupImage; 2],
        projections: [&Projection; 2],
        tol: &Tolerances,
    ) -> Counts {
        count_chunks::<BOTH, SEEN>(points, images, projections, tol)
    }
}

/// The counts; with `BOTH` false only the left image is read and counted (the right
/// counts and `confirmed` are then left at zero); with `SEEN` false the points on the
/// images are not counted.
#[inline(always)]
fn count_chunks<const BOTH: bool, const SEEN: bool>(
    points: &PointSet,
    [left, right]: [&LookupImage; 2],
    [pl, pr]: [&Projection; 2],
    tol: &Tolerances,
) -> Counts {
    let (mut a, mut b) = (Chunk::new(), Chunk::new());
    let mut c = Counts::default();
    let (inner_x, inner_y) = (&points.inner_x[..], &points.inner_y[..]);
    let chromatic = points.chromatic;
    for start in (0..chromatic).step_by(CHUNK) {
        let r = start..(start + CHUNK).min(chromatic);
        let (xs, ys) = (&inner_x[r.clone()], &inner_y[r.clone()]);
        let tl = a.read(left, pl, xs, ys);
        let model = points.inner_code[r.clone()].iter().zip(&points.inner_sat[r]);
        if BOTH {
            let tr = b.read(right, pr, xs, ys);
            for ((&l, &r), (&code, &sat)) in tl.iter().zip(tr).zip(model) {
                let ml = chromatic_match(l, code, sat, tol);
                c.close[0] = c.close[0].wrapping_add(ml as u32);
                c.close[1] = c.close[1].wrapping_add(chromatic_match(r, code, sat, tol) as u32);
                if SEEN {
                    c.inner_seen[0] = c.inner_seen[0].wrapping_add(on_image(l) as u32);
                    c.inner_seen[1] = c.inner_seen[1].wrapping_add(on_image(r) as u32);
                }
                c.confirmed = c
                    .confirmed
                    .wrapping_add((ml & ((r & 0xff) < 180) & same_colour(l, r, tol)) as u32);
            }
        } else {
            for (&l, (&code, &sat)) in tl.iter().zip(model) {
                c.close[0] = c.close[0].wrapping_add(chromatic_match(l, code, sat, tol) as u32);
                if SEEN {
                    c.inner_seen[0] = c.inner_seen[0].wrapping_add(on_image(l) as u32);
                }
            }
        }
    }
    for start in (chromatic..inner_x.len()).step_by(CHUNK) {
        let r = start..(start + CHUNK).min(inner_x.len());
        let (xs, ys) = (&inner_x[r.clone()], &inner_y[r.clone()]);
        let tl = a.read(left, pl, xs, ys);
        let codes = &points.inner_code[r];
        if BOTH {
            let tr = b.read(right, pr, xs, ys);
            for ((&l, &r), &code) in tl.iter().zip(tr).zip(codes) {
                let (ml, mr) = ((l & 0xff) == code as u32, (r & 0xff) == code as u32);
                c.close[0] = c.close[0].wrapping_add(ml as u32);
                c.close[1] = c.close[1].wrapping_add(mr as u32);
                c.confirmed = c.confirmed.wrapping_add((ml & mr) as u32);
                if SEEN {
                    c.inner_seen[0] = c.inner_seen[0].wrapping_add(on_image(l) as u32);
                    c.inner_seen[1] = c.inner_seen[1].wrapping_add(on_image(r) as u32);
                }
            }
        } else {
            for (&l, &code) in tl.iter().zip(codes) {
                c.close[0] = c.close[0].wrapping_add(((l & 0xff) == code as u32) as u32);
                if SEEN {
                    c.inner_seen[0] = c.inner_seen[0].wrapping_add(on_image(l) as u32);
                }
            }
        }
    }
    let n_outer = points.outer_x.len();
    let mut target = [0u32; 2];
    let seen = |t: &[u32]| count_true(t.iter().map(|&t| on_image(t)));
    for start in (0..n_outer).step_by(CHUNK) {
        let r = start..(start + CHUNK).min(n_outer);
        let (xs, ys) = (&points.outer_x[r.clone()], &points.outer_y[r]);
        let tl = a.read(left, pl, xs, ys);
        target[0] = target[0].wrapping_add(tol.outer.targets(tl));
        if SEEN {
            c.outer_seen[0] = c.outer_seen[0].wrapping_add(seen(tl));
        }
        if BOTH {
            let tr = b.read(right, pr, xs, ys);
            target[1] = target[1].wrapping_add(tol.outer.targets(tr));
            if SEEN {
                c.outer_seen[1] = c.outer_seen[1].wrapping_add(seen(tr));
            }
        }
    }
    c.background = [
        (n_outer as u32).wrapping_sub(target[0]),
        if BOTH {
            (n_outer as u32).wrapping_sub(target[1])
        } else {
            0
        },
    ];
    c
}

#[cfg(test)]
mod tests;
