//! The texture terms of the robust search: at a candidate pose, the model's inner
//! points are looked up in both images' brightness. Where the pose is right, the left
//! and right samples show the same surface point (they correlate: **stereo**), and they
//! follow the photo's own brightness pattern (**structure**). A same-coloured blob at
//! another depth, or the right place at a wrong tilt, fails one or both: the hue that
//! the colour fitness compares is flat there, brightness is not. Both are normalised
//! correlations, so a change of brightness or contrast leaves them unchanged.

use image::RgbImage;
use nalgebra::Isometry3;

use crate::camera::{Intrinsics, StereoRig};
use crate::estimator::fitness::{view_weight, PointProjector, PointSet};
use crate::estimator::pose::PoseSize;
use crate::vision::frame::Region;
use crate::vision::lookup::SbsBytes;
use crate::vision::simd::avx2_multiversion;

mod sample;
use sample::Samples;

/// One eye's brightness (HSV value, the maximum of R, G and B), row-major, and its
/// detail: the brightness minus its 5 × 5 mean, which keeps only the fine texture.
#[derive(Debug, Clone)]
pub struct Brightness {
    /// Image pixel of the top-left corner (a region of the image; (0, 0) for all of it).
    origin: (f32, f32),
    width: usize,
    height: usize,
    /// Each pixel's brightness and detail, side by side: a sample reads both from the
    /// same cache lines.
    px: Vec<[f32; 2]>,
    /// Variance of the sensor noise in the detail, estimated from the image's
    /// flattest blocks.
    noise_var: f32,
}

/// Half-width of the box mean that [`Brightness`] subtracts for the detail.
const DETAIL_RADIUS: usize = 2;

/// Buffers that [`Brightness::refill_region`] reuses: a tracking frame reads its
/// regions' brightness without allocating.
#[derive(Debug, Default)]
pub struct Scratch {
    values: Vec<f32>,
    rows: Vec<f32>,
    detail: Vec<f32>,
    blocks: Vec<f32>,
}

impl Scratch {
    /// Room for regions of up to `pixels` pixels.
    pub fn reserve(&mut self, pixels: usize) {
        for buf in [&mut self.values, &mut self.rows, &mut self.detail] {
            buf.reserve(pixels.saturating_sub(buf.len()));
        }
        self.blocks.reserve((pixels / 64).saturating_sub(self.blocks.len()));
    }
}

impl Brightness {
    /// The HSV value of every pixel of `img`, and its detail.
    pub fn of(img: &RgbImage) -> Self {
        let (width, height) = (img.width() as usize, img.height() as usize);
        let mut scratch = Scratch {
            values: img.pixels().map(|p| hsv_value(&p.0)).collect(),
            ..Scratch::default()
        };
        let mut b = Self::empty();
        b.fill(width, height, (0, 0), &mut scratch);
        b
    }

    /// [`Brightness::of`] the pixels of `region` in eye `eye` (0 left, 1 right) of a
    /// side-by-side frame; samples keep the image's pixel coordinates.
    pub fn of_region(frame: &SbsBytes, eye: usize, region: &Region) -> Self {
        let mut b = Self::empty();
        b.refill_region(frame, eye, region, &mut Scratch::default());
        b
    }

    /// No pixels: every sample is outside.
    pub fn empty() -> Self {
        Self {
            origin: (0.0, 0.0),
            width: 0,
            height: 0,
            px: Vec::new(),
            noise_var: 0.0,
        }
    }

    /// Room for regions of up to `pixels` pixels.
    pub fn reserve(&mut self, pixels: usize) {
        self.px.reserve(pixels.saturating_sub(self.px.len()));
    }

    /// This brightness becomes [`Brightness::of_region`]`(frame, eye, region)`, in the
    /// buffers it and `scratch` hold (no allocation where they are large enough).
    pub fn refill_region(&mut self, frame: &SbsBytes, eye: usize, region: &Region, scratch: &mut Scratch) {
        let cols = region.cols.start.min(frame.width)..region.cols.end.min(frame.width);
        let rows = region.rows.start.min(frame.height)..region.rows.end.min(frame.height);
        let (width, height) = (cols.len(), rows.len());
        let px = &mut scratch.values;
        px.clear();
        for v in rows.clone() {
            match frame.rgb_row(eye, v, cols.clone()) {
                Some(row) => hsv_row(row, px),
                None => px.extend(
                    cols.clone()
                        .map(|u| frame.rgb_at(eye, u, v).map_or(0.0, |p| hsv_value(&p))),
                ),
            }
        }
        self.fill(width, height, (cols.start, rows.start), scratch);
    }

    /// Sets the brightness to `scratch.values` (`width` × `height` pixels whose corner
    /// is image pixel `origin`) and works out its detail and noise.
    fn fill(&mut self, width: usize, height: usize, origin: (usize, usize), scratch: &mut Scratch) {
        let Scratch {
            values,
            rows,
            detail,
            blocks,
        } = scratch;
        box_mean_into(values, width, height, DETAIL_RADIUS, rows, detail);
        detail.iter_mut().zip(values.iter()).for_each(|(d, a)| *d = a - *d);
        self.noise_var = noise_variance(detail, width, height, blocks);
        self.origin = (origin.0 as f32, origin.1 as f32);
        (self.width, self.height) = (width, height);
        self.px.clear();
        pair_up(values, detail, &mut self.px);
    }
}

avx2_multiversion! {
    /// Appends the HSV value of each RGB8 pixel of `row`.
    fn hsv_row(row: &[u8], out: &mut Vec<f32>) {
        out.extend(row.chunks_exact(3).map(hsv_value));
    }
}

avx2_multiversion! {
    /// Appends each pixel's brightness and detail side by side.
    fn pair_up(values: &[f32], detail: &[f32], out: &mut Vec<[f32; 2]>) {
        out.extend(values.iter().zip(detail).map(|(&a, &d)| [a, d]));
    }
}

/// A pixel's HSV value: its largest channel.
#[inline]
fn hsv_value(rgb: &[u8]) -> f32 {
    rgb.iter().copied().max().unwrap_or(0) as f32
}

/// The noise variance of a detail image: the variance of its flattest 8 × 8 blocks
/// (the 5th percentile), where only noise is left.
fn noise_variance(detail: &[f32], w: usize, h: usize, vars: &mut Vec<f32>) -> f32 {
    const B: usize = 8;
    vars.clear();
    for by in 0..h / B {
        for bx in 0..w / B {
            let (mut s, mut ss) = (0.0f32, 0.0f32);
            for y in by * B..(by + 1) * B {
                for &d in &detail[y * w + bx * B..y * w + (bx + 1) * B] {
                    s += d;
                    ss += d * d;
                }
            }
            let n = (B * B) as f32;
            vars.push(ss / n - (s / n).powi(2));
        }
    }
    if vars.is_empty() {
        return 0.0;
    }
    let k = vars.len() / 20;
    *vars.select_nth_unstable_by(k, f32::total_cmp).1
}

/// The mean of each pixel's `(2r + 1)²` neighbourhood (clamped at the edges).
#[cfg(test)]
fn box_mean(px: &[f32], w: usize, h: usize, r: usize) -> Vec<f32> {
    let mut out = Vec::new();
    box_mean_into(px, w, h, r, &mut Vec::new(), &mut out);
    out
}

avx2_multiversion! {
    /// `out` = the box mean of `px` (see `box_mean`): a pass along each row into `rows`,
    /// then one adding whole rows (in memory order, not down columns). Each buffer is
    /// written before it is read (a fresh buffer's pages are then mapped once, not on a
    /// read and again on the write).
    fn box_mean_into(px: &[f32], w: usize, h: usize, r: usize, rows: &mut Vec<f32>, out: &mut Vec<f32>) {
        rows.clear();
        out.clear();
        if w == 0 || h == 0 {
            out.extend(px.iter().map(|_| 0.0));
            return;
        }
        let window = |k: usize, len: usize| (k.saturating_sub(r), (k + r).min(len - 1));
        for src in px.chunks_exact(w) {
            let edge = |k: usize| {
                let (a, b) = window(k, w);
                src[a..=b].iter().sum::<f32>() / (b - a + 1) as f32
            };
            if w <= 2 * r {
                rows.extend((0..w).map(edge));
                continue;
            }
            rows.extend((0..r).map(edge));
            add_windows(src, 2 * r + 1, rows);
            rows.extend((w - r..w).map(edge));
        }
        for y in 0..h {
            let (a, b) = window(y, h);
            let start = out.len();
            out.extend_from_slice(&rows[a * w..(a + 1) * w]);
            let dst = &mut out[start..];
            for src in rows[(a + 1) * w..(b + 1) * w].chunks_exact(w) {
                dst.iter_mut().zip(src).for_each(|(d, s)| *d += s);
            }
            let n = (b - a + 1) as f32;
            dst.iter_mut().for_each(|d| *d /= n);
        }
    }
}

/// Appends the mean of each whole window of `n` values of `src`, in order: whole
/// slices added one after another (the loop vectorises), the same sums as adding each
/// window's values from its first.
#[inline(always)]
fn add_windows(src: &[f32], n: usize, out: &mut Vec<f32>) {
    let len = src.len() + 1 - n;
    let start = out.len();
    out.extend_from_slice(&src[..len]);
    let sums = &mut out[start..];
    for j in 1..n {
        sums.iter_mut().zip(&src[j..j + len]).for_each(|(d, s)| *d += s);
    }
    sums.iter_mut().for_each(|d| *d /= n as f32);
}

/// The texture terms of one candidate, each a normalised correlation in `[-1, 1]`
/// over the points seen by both cameras, weighted by their share (see
/// `seen_weight`); 0 where a signal is flat.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Texture {
    /// Left against right brightness detail at the same model points.
    pub stereo: f64,
    /// The photo's brightness against each image's, averaged over the two eyes.
    pub structure: f64,
}

impl Texture {
    /// Their sum, what the search adds to the colour score (weighted).
    pub fn sum(&self) -> f64 {
        self.stereo + self.structure
    }
}

/// Running sums of a normalised cross-correlation.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Ncc {
    /// Summed noise variances of the two signals' samples (for the correction).
    noise_a: f64,
    noise_b: f64,
    n: f64,
    sa: f64,
    sb: f64,
    saa: f64,
    sbb: f64,
    sab: f64,
}

/// Below this standard deviation (grey levels) a signal counts as flat.
const FLAT_STD: f64 = 2.0;

impl Ncc {
    #[inline]
    pub(super) fn add(&mut self, a: f32, b: f32) {
        let (a, b) = (a as f64, b as f64);
        self.n += 1.0;
        self.sa += a;
        self.sb += b;
        self.saa += a * a;
        self.sbb += b * b;
        self.sab += a * b;
    }

    pub(super) fn value(&self) -> f64 {
        self.corrected(false)
    }

    /// The two signals' variances; `denoised`: less their noise.
    fn variances(&self, denoised: bool) -> (f64, f64) {
        let (na, nb) = if denoised {
            (self.noise_a / self.n, self.noise_b / self.n)
        } else {
            (0.0, 0.0)
        };
        (
            self.saa / self.n - (self.sa / self.n).powi(2) - na,
            self.sbb / self.n - (self.sb / self.n).powi(2) - nb,
        )
    }

    /// Whether either signal is flat (of at least 8 samples): what is left of the
    /// detail of a card that motion blur or defocus smoothed.
    fn flat(&self, denoised: bool) -> bool {
        self.n >= 8.0 && either_flat(self.variances(denoised))
    }

    /// The correlation; `denoised`: of the signals without their noise (the classic
    /// correction for attenuation: the noise variance leaves the denominator), so that
    /// a noisy image of the right pose still correlates near 1. Zero for fewer than 8
    /// samples or a flat signal.
    fn corrected(&self, denoised: bool) -> f64 {
        if self.n < 8.0 {
            return 0.0;
        }
        let (va, vb) = self.variances(denoised);
        if either_flat((va, vb)) {
            return 0.0;
        }
        ((self.sab / self.n - self.sa * self.sb / (self.n * self.n)) / (va * vb).sqrt()).clamp(-1.0, 1.0)
    }
}

/// Whether either of two variances is below [`FLAT_STD`]².
fn either_flat((va, vb): (f64, f64)) -> bool {
    va < FLAT_STD * FLAT_STD || vb < FLAT_STD * FLAT_STD
}

/// How [`score`] reads the texture terms.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Reading {
    /// The stereo term corrected for the images' noise: their noise variance leaves the
    /// correlation's denominator.
    pub denoised: bool,
    /// Robust mode's rule for a model partly out of view: a correlation over part of the
    /// model counts by its view weight, not in proportion to the share seen.
    pub partial_view: bool,
    /// Where the detail is flat in either eye (motion blur), the stereo term correlates
    /// the two eyes' brightness instead of being 0. A tracking frame's ranking only: a
    /// whole-frame search or a status must not take a smooth wall's agreement with
    /// itself for the card's.
    pub brightness_where_flat: bool,
}

/// The stereo term from the correlations of the two eyes' `detail` and `brightness`
/// at the same model points: the detail's, or, with `reading.brightness_where_flat`
/// where the detail is flat, the brightness's. Motion blur across a card at 600 mm/s
/// (10 px at 30 fps) leaves its detail flat in both eyes while the brightness still
/// differs from point to point and agrees between the eyes only at the right depth and
/// tilt. A tracking frame ranks its candidates so: they are near a followed pose. A
/// whole-frame search and the status do not, as a smooth wall agrees with itself at
/// many depths.
fn stereo_term(detail: &Ncc, brightness: &Ncc, reading: Reading) -> f64 {
    if reading.brightness_where_flat && detail.flat(reading.denoised) {
        brightness.value()
    } else {
        detail.corrected(reading.denoised)
    }
}

/// Both texture terms of candidate `c` (hand frame; `left_from_hand` the hand–eye
/// transform) on images `[left, right]` seen through `rig`, read as `reading` says:
/// stereo on the detail (or, where it is flat, the brightness: [`Reading`]), structure
/// on the brightness itself.
///
/// The stereo term leaves out the points within `EDGE_PX` of the model's edge: their
/// detail mixes in the background just beyond the card, which each eye sees from
/// another angle (the wall behind a card 1 m away is 40 px apart in the two eyes), so
/// at the true pose they disagreed and a model a few per cent smaller matched better.
pub fn score(
    points: &PointSet,
    rig: &StereoRig,
    eyes: [&Brightness; 2],
    left_from_hand: &Isometry3<f64>,
    c: &PoseSize,
    reading: Reading,
) -> Texture {
    let (mut stereo, mut model_left, mut model_right) = (Ncc::default(), Ncc::default(), Ncc::default());
    let mut stereo_brightness = Ncc::default();
    both_eyes(
        points,
        rig,
        eyes,
        left_from_hand,
        c,
        |inside, m, (a, da, na), (b, db, nb)| {
            if inside {
                stereo.add(da, db);
                stereo.noise_a += na as f64;
                stereo.noise_b += nb as f64;
                if reading.brightness_where_flat {
                    stereo_brightness.add(a, b);
                }
            }
            model_left.add(m as f32, a);
            model_right.add(m as f32, b);
        },
    );
    let seen = seen_weight(model_left.n / points.inner_v.len().max(1) as f64, reading.partial_view);
    Texture {
        stereo: stereo_term(&stereo, &stereo_brightness, reading) * seen,
        structure: (model_left.value() + model_right.value()) / 2.0 * seen,
    }
}

/// One eye's sample at a point: brightness, detail and the detail's noise variance.
pub(super) type Sample = (f32, f32, f32);

/// Both eyes' samples at the inner points of `points` that both see for candidate `c`:
/// `visit(inside, m, left, right)`, `inside` when the point is at least [`EDGE_PX`]
/// inside the model's edge in the left image, `m` the photo's brightness there.
pub(super) fn both_eyes(
    points: &PointSet,
    rig: &StereoRig,
    eyes: [&Brightness; 2],
    left_from_hand: &Isometry3<f64>,
    c: &PoseSize,
    mut visit: impl FnMut(bool, u8, Sample, Sample),
) {
    let left_from_model = left_from_hand * c.hand_from_model();
    let left = PointProjector::new(&rig.left, &left_from_model, c);
    let right = PointProjector::new(&rig.right, &(rig.right_from_left * left_from_model), c);
    let inside = EdgeMargin::new(points, &left);
    let mut px = [[0.0f32; BATCH]; 4];
    let mut samples = [Samples::new(), Samples::new()];
    for (xs, ys, ms) in batches(points) {
        let [ul, vl, ur, vr] = &mut px;
        project_batch(&left, xs, ys, ul, vl);
        project_batch(&right, xs, ys, ur, vr);
        let [sl, sr] = &mut samples;
        eyes[0].sample_batch(ul, vl, sl);
        eyes[1].sample_batch(ur, vr, sr);
        for (i, ((&x, &y), &m)) in xs.iter().zip(ys).zip(ms).enumerate() {
            if sl.seen(i) && sr.seen(i) {
                visit(inside.holds(x, y), m, sl.at(i), sr.at(i));
            }
        }
    }
}

/// Model points projected at a time: their pixels are computed in a loop the compiler
/// vectorises, then sampled one by one.
const BATCH: usize = 256;

/// The inner points of `points` in runs of [`BATCH`]: x, y and the photo's brightness.
fn batches(points: &PointSet) -> impl Iterator<Item = (&[f32], &[f32], &[u8])> {
    let xy = points.inner_x.chunks(BATCH).zip(points.inner_y.chunks(BATCH));
    xy.zip(points.inner_v.chunks(BATCH)).map(|((xs, ys), ms)| (xs, ys, ms))
}

avx2_multiversion! {
    /// The pixels of model points `(xs[i], ys[i])` through `project`, into `us` and `vs`
    /// (the first [`BATCH`] of them).
    fn project_batch(project: &PointProjector, xs: &[f32], ys: &[f32], us: &mut [f32; BATCH], vs: &mut [f32; BATCH]) {
        for (((&x, &y), u), v) in xs.iter().zip(ys).zip(us.iter_mut()).zip(vs.iter_mut()) {
            (*u, *v) = project.pixel(x, y);
        }
    }
}

/// Image pixels from the model's edge within which a point's detail reads the
/// background too: the detail's box mean (radius [`DETAIL_RADIUS`]), the bilinear
/// sample and the card's anti-aliased rim.
const EDGE_PX: f32 = DETAIL_RADIUS as f32 + 2.0;

/// The part of the model at least [`EDGE_PX`] inside its edge in the left image, in
/// model (photo) pixels from the box centre.
struct EdgeMargin {
    half: [f32; 2],
}

impl EdgeMargin {
    /// The margin of `points` as the projector `left` shows them: the outermost points
    /// stand for the edge, and the image scale along each model axis is measured
    /// between them.
    fn new(points: &PointSet, left: &PointProjector) -> Self {
        let extent = |v: &[f32]| v.iter().fold(0.0f32, |m, a| m.max(a.abs()));
        let (ex, ey) = (extent(&points.inner_x), extent(&points.inner_y));
        let scale = |a: (f32, f32), b: (f32, f32), span: f32| {
            let d = (a.0 - b.0).hypot(a.1 - b.1);
            if span > 0.0 && d.is_finite() && d > 0.0 {
                d / span
            } else {
                f32::INFINITY
            }
        };
        let sx = scale(left.pixel(ex, 0.0), left.pixel(-ex, 0.0), 2.0 * ex);
        let sy = scale(left.pixel(0.0, ey), left.pixel(0.0, -ey), 2.0 * ey);
        Self {
            half: [ex - EDGE_PX / sx, ey - EDGE_PX / sy],
        }
    }

    #[inline]
    fn holds(&self, x: f32, y: f32) -> bool {
        x.abs() <= self.half[0] && y.abs() <= self.half[1]
    }
}

/// The structure term in one camera only (the scan, before depth is known).
pub fn structure_in(
    points: &PointSet,
    cam: &Intrinsics,
    eye: &Brightness,
    left_from_hand: &Isometry3<f64>,
    c: &PoseSize,
    partial_view: bool,
) -> f64 {
    let project = PointProjector::new(cam, &(left_from_hand * c.hand_from_model()), c);
    let mut ncc = Ncc::default();
    let [mut us, mut vs] = [[0.0f32; BATCH]; 2];
    let mut samples = Samples::new();
    for (xs, ys, ms) in batches(points) {
        project_batch(&project, xs, ys, &mut us, &mut vs);
        eye.sample_batch(&us, &vs, &mut samples);
        for (i, &m) in ms.iter().enumerate() {
            if samples.seen(i) {
                ncc.add(m as f32, samples.value(i));
            }
        }
    }
    ncc.value() * seen_weight(ncc.n / points.inner_v.len().max(1) as f64, partial_view)
}

/// How much a correlation over the `share` of a model's points seen counts: by
/// [`view_weight`] with `partial_view` (robust mode's rule, [`Scorer::partial_view`]),
/// else in proportion to the share.
///
/// [`Scorer::partial_view`]: crate::estimator::fitness::Scorer::partial_view
fn seen_weight(share: f64, partial_view: bool) -> f64 {
    if partial_view {
        view_weight(share)
    } else {
        share
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vision::frame::StereoImages;
    use crate::vision::PixelFormat;

    /// A `w × h` pseudo-random RGB image.
    fn noise_image(w: u32, h: u32, seed: u32) -> RgbImage {
        RgbImage::from_fn(w, h, |x, y| {
            let k = (x * 7919 + y * 104_729 + seed * 31).wrapping_mul(2_654_435_761);
            image::Rgb([(k >> 8) as u8, (k >> 16) as u8, (k >> 24) as u8])
        })
    }

    /// The RGB8 side-by-side bytes of two eyes of the same size.
    fn side_by_side(left: &RgbImage, right: &RgbImage) -> Vec<u8> {
        let (left, right) = (left.clone(), right.clone());
        StereoImages { left, right }.to_sbs().into_raw()
    }

    /// `bytes` as a side-by-side RGB8 frame of two `w × h` eyes.
    fn rgb_frame(bytes: &[u8], w: usize, h: usize) -> SbsBytes<'_> {
        SbsBytes {
            bytes,
            width: w,
            height: h,
            row_stride: 6 * w,
            format: PixelFormat::Rgb8,
        }
    }

    /// Running sums over pairs.
    fn ncc_of(pairs: impl Iterator<Item = (f32, f32)>) -> Ncc {
        let mut ncc = Ncc::default();
        pairs.for_each(|(a, b)| ncc.add(a, b));
        ncc
    }

    #[test]
    fn where_the_detail_is_flat_the_stereo_term_can_read_the_brightness() {
        let wave = |i: usize| 100.0 + 60.0 * (i as f32 * 0.05).sin();
        // The same brightness in both eyes; detail of ±1 grey level (flat), unrelated.
        let same = ncc_of((0..200).map(|i| (wave(i), wave(i) + 1.0)));
        let flat = ncc_of((0..200).map(|i| (if i % 2 == 0 { 1.0 } else { -1.0 }, if i % 3 == 0 { 1.0 } else { -1.0 })));
        let plain = Reading {
            denoised: true,
            ..Reading::default()
        };
        let blurred = Reading {
            brightness_where_flat: true,
            ..plain
        };
        assert_eq!(stereo_term(&flat, &same, plain), 0.0);
        assert!((stereo_term(&flat, &same, blurred) - 1.0).abs() < 1e-6);
        // At a wrong depth the eyes' brightness is shifted along the card: it agrees less.
        let shifted = ncc_of((0..200).map(|i| (wave(i), wave(i + 20))));
        assert!(stereo_term(&flat, &shifted, blurred) < 0.6);
        // Where there is detail, it decides.
        let opposed = ncc_of((0..200).map(|i| (10.0 * (i as f32 * 0.7).sin(), -10.0 * (i as f32 * 0.7).sin())));
        assert!((stereo_term(&opposed, &same, blurred) + 1.0).abs() < 1e-6);
    }

    #[test]
    fn box_mean_is_the_mean_of_the_clamped_window() {
        let (w, h, r) = (9, 6, 2);
        let px: Vec<f32> = (0..w * h).map(|i| ((i * 37) % 101) as f32).collect();
        let mean = box_mean(&px, w, h, r);
        for y in 0..h {
            for x in 0..w {
                let (xs, ys) = (
                    x.saturating_sub(r)..=(x + r).min(w - 1),
                    y.saturating_sub(r)..=(y + r).min(h - 1),
                );
                let n = (xs.clone().count() * ys.clone().count()) as f32;
                let px = &px;
                let sum: f32 = ys.flat_map(|yy| xs.clone().map(move |xx| px[yy * w + xx])).sum();
                assert!((mean[y * w + x] - sum / n).abs() < 1e-4, "({x}, {y})");
            }
        }
        assert!(box_mean(&[], 0, 0, r).is_empty());
    }

    #[test]
    fn a_brightness_read_again_into_its_buffers_equals_a_fresh_read() {
        let img = noise_image(40, 30, 3);
        let bytes = side_by_side(&img, &img);
        let frame = rgb_frame(&bytes, 40, 30);
        let (mut kept, mut scratch) = (Brightness::empty(), Scratch::default());
        scratch.reserve(40 * 30);
        kept.reserve(40 * 30);
        // A large region, then a smaller one elsewhere: nothing of the first may remain.
        for region in [(0..40, 0..30), (30..38, 20..29), (5..25, 2..12)] {
            let region = Region {
                cols: region.0,
                rows: region.1,
            };
            kept.refill_region(&frame, 1, &region, &mut scratch);
            let fresh = Brightness::of_region(&frame, 1, &region);
            assert_eq!(
                (kept.width, kept.height, kept.origin),
                (fresh.width, fresh.height, fresh.origin)
            );
            assert_eq!(kept.px, fresh.px);
            assert_eq!(kept.noise_var, fresh.noise_var);
        }
    }

    #[test]
    fn a_region_of_a_frame_reads_as_the_same_crop_of_the_image() {
        let (left, right) = (noise_image(40, 30, 1), noise_image(40, 30, 2));
        let bytes = side_by_side(&left, &right);
        let frame = rgb_frame(&bytes, 40, 30);
        // Partly outside the image: clamped to columns 25..40, rows 4..30.
        let region = Region {
            cols: 25..50,
            rows: 4..33,
        };
        for (eye, img) in [&left, &right].into_iter().enumerate() {
            let read = Brightness::of_region(&frame, eye, &region);
            let crop = Brightness::of(&image::imageops::crop_imm(img, 25, 4, 15, 26).to_image());
            assert_eq!((read.width, read.height, read.origin), (15, 26, (25.0, 4.0)));
            assert_eq!(read.px, crop.px, "eye {eye}");
        }
    }
}
