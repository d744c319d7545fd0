//! Lookup images: what the fitness reads per pixel (colour code and saturation, or
//! the raw hue for the paper's outer test) packed into one `u16`, with a ring of outside
//! texels around the covered region. The kernel clamps a projected point onto the
//! padded region instead of branching on whether it is inside: a point off the region
//! lands on the ring and reads "outside". Two bytes per pixel keep an HD image's texels
//! at 1.8 MB, so the kernel's scattered reads hit the caches more often.
//!
//! A lookup image covers either a whole image (one-shot estimates) or only a region of
//! interest around the predicted pose (tracking), converted straight from the frame's
//! bytes as they arrived, row by row in loops the compiler vectorises.

use rayon::prelude::*;

use crate::camera::StereoRig;
use crate::vision::color::{bt601, yuv_to_rgb, ColorClasses, BLACK, GRAY, WHITE};
use image::RgbImage;

use crate::vision::frame::{coarse_levels, ColorPlane, FrameLevel, PixelColor, Region, StereoImages};
use crate::vision::simd::avx2_multiversion;
use crate::vision::PixelFormat;

/// Colour code of a texel outside the image: it matches no model colour and, for outer
/// points, counts as target (a mismatch), as points outside an image do.
pub const OUTSIDE: u8 = 255;

/// What the fitness reads per pixel: bits 0–7 the [`crate::vision::color`] code (or
/// [`OUTSIDE`]), bits 8–15 the second byte of the [`TexelRule`] (the saturation, or the
/// raw OpenCV hue).
pub type Texel = u16;

/// Packs a pixel's colour code and second byte.
#[inline(always)]
pub fn texel(code: u8, second: u8) -> Texel {
    code as Texel | (second as Texel) << 8
}

/// The texel of the ring around the image.
pub const OUTSIDE_TEXEL: Texel = OUTSIDE as Texel;

/// The fitness kernel computes indices in `f32` and rounds with the 2²³ trick, so a
/// padded image holds fewer texels than this (2K has 2.7 M).
pub const MAX_TEXELS: usize = 1 << 23;

/// What a texel's second byte holds: what the outer test of the search needs besides
/// the colour code.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SecondByte {
    /// The saturation (robust mode: saturation-aware matches and colour-class outer test).
    Saturation,
    /// The raw OpenCV hue, 0 for grey pixels (paper mode: eq. 16 on the raw hue).
    RawHue,
}

/// How a pixel's colour becomes a texel: the Table 1 classes and the second byte.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TexelRule {
    /// The Table 1 colour classes.
    pub classes: ColorClasses,
    /// What the second byte holds.
    pub second: SecondByte,
    /// Gains `[r, g, b]` applied to a row's pixels before they are classed (tracking
    /// under changing light: [`crate::estimator::exposure`]); `[1.0; 3]` leaves them as
    /// they are. A clipped pixel (a channel at [`CLIPPED`] or more) keeps its value: its
    /// true brightness is unknown.
    pub gains: [f32; 3],
}

/// A channel value from which a pixel counts as clipped (over-exposed).
pub const CLIPPED: f32 = 250.0;

/// A pixel's channels scaled by `gains` (at most 255); a clipped pixel as it is.
#[inline(always)]
pub fn gained(rgb: [f32; 3], gains: [f32; 3]) -> [f32; 3] {
    let keep = rgb[0].max(rgb[1]).max(rgb[2]) >= CLIPPED;
    std::array::from_fn(|c| if keep { rgb[c] } else { (rgb[c] * gains[c]).min(255.0) })
}

impl TexelRule {
    /// The texel of a pixel with colour code `code`, saturation `sat` and raw OpenCV hue
    /// `hue`.
    #[inline(always)]
    pub fn texel(&self, code: u8, sat: u8, hue: u8) -> Texel {
        texel(
            code,
            match self.second {
                SecondByte::Saturation => sat,
                SecondByte::RawHue => hue,
            },
        )
    }

    /// This rule with the pixels scaled by `gains` first.
    pub fn with_gains(self, gains: [f32; 3]) -> Self {
        Self { gains, ..self }
    }

    /// Applies [`TexelRule::gains`] to a chunk of channel values, in place.
    #[inline(always)]
    fn apply_gains<const N: usize>(&self, r: &mut [f32; N], g: &mut [f32; N], b: &mut [f32; N]) {
        for i in 0..N {
            [r[i], g[i], b[i]] = gained([r[i], g[i], b[i]], self.gains);
        }
    }

    /// The texel of one pixel's [`PixelColor`].
    pub fn of(&self, c: &PixelColor) -> Texel {
        self.texel(c.code, c.sat, c.hue)
    }

    /// Texels of a row of packed RGB8 pixels (`rgb.len() == 3 * out.len()`), exactly as
    /// [`crate::vision::color::rgb_to_hsv`] and [`TexelRule::texel`] give them one by one.
    pub fn rgb_row(&self, rgb: &[u8], out: &mut [Texel]) {
        rgb_row_texels(self, rgb, out)
    }

    #[inline(always)]
    fn rgb_row_chunks(&self, rgb: &[u8], out: &mut [Texel]) {
        const N: usize = 64;
        let mut tail = [0u8; 3 * N];
        for (src, dst) in rgb.chunks(3 * N).zip(out.chunks_mut(N)) {
            // Fixed-size chunks let the compiler turn every loop below into vector code.
            let src: &[u8; 3 * N] = match src.try_into() {
                Ok(full) => full,
                Err(_) => {
                    tail[..src.len()].copy_from_slice(src);
                    &tail
                }
            };
            let (mut r, mut g, mut b) = ([0f32; N], [0f32; N], [0f32; N]);
            for i in 0..N {
                (r[i], g[i], b[i]) = (src[3 * i] as f32, src[3 * i + 1] as f32, src[3 * i + 2] as f32);
            }
            self.apply_gains(&mut r, &mut g, &mut b);
            let mut texels = [0; N];
            for (i, t) in texels.iter_mut().enumerate() {
                let (h, s, v) = hsv(r[i], g[i], b[i]);
                *t = self.texel_of_hsv(h, s, v);
            }
            dst.copy_from_slice(&texels[..dst.len()]);
        }
    }

    /// Texels of a row of YUYV pixels starting at an even pixel (`Y0 U Y1 V` per pair of
    /// pixels, `yuyv` holding the pairs that cover `out`), exactly as
    /// [`crate::vision::color::yuv_to_rgb`], [`crate::vision::color::rgb_to_hsv`] and
    /// [`TexelRule::texel`] give them one by one, without an RGB image in between.
    pub fn yuyv_row(&self, yuyv: &[u8], out: &mut [Texel]) {
        yuyv_row_texels(self, yuyv, out)
    }

    #[inline(always)]
    fn yuyv_row_chunks(&self, yuyv: &[u8], out: &mut [Texel]) {
        use bt601::*;
        const N: usize = 64;
        let mut tail = [0u8; 2 * N];
        for (src, dst) in yuyv.chunks(2 * N).zip(out.chunks_mut(N)) {
            let src: &[u8; 2 * N] = match src.try_into() {
                Ok(full) => full,
                Err(_) => {
                    tail[..src.len()].copy_from_slice(src);
                    &tail
                }
            };
            // Luma scaled, and the chroma terms of each pixel (shared by a pair).
            let (mut yy, mut ru, mut gu, mut bu) = ([0i32; N], [0i32; N], [0i32; N], [0i32; N]);
            for k in 0..N / 2 {
                let q = &src[4 * k..4 * k + 4];
                let (u, v) = (q[1] as i32 - 128, q[3] as i32 - 128);
                let (r, g, b) = (HALF + CVR * v, HALF + CVG * v + CUG * u, HALF + CUB * u);
                for (j, y) in [(2 * k, q[0]), (2 * k + 1, q[2])] {
                    yy[j] = (y as i32 - 16).max(0) * CY;
                    (ru[j], gu[j], bu[j]) = (r, g, b);
                }
            }
            let (mut r, mut g, mut b) = ([0f32; N], [0f32; N], [0f32; N]);
            for i in 0..N {
                let channel = |c: i32| ((yy[i] + c) >> SHIFT).clamp(0, 255) as f32;
                (r[i], g[i], b[i]) = (channel(ru[i]), channel(gu[i]), channel(bu[i]));
            }
            self.apply_gains(&mut r, &mut g, &mut b);
            let mut texels = [0; N];
            for (i, t) in texels.iter_mut().enumerate() {
                let (h, s, v) = hsv(r[i], g[i], b[i]);
                *t = self.texel_of_hsv(h, s, v);
            }
            dst.copy_from_slice(&texels[..dst.len()]);
        }
    }

    /// [`TexelRule::texel`] of an HSV triple, in `u32` arithmetic with selects (vector code).
    #[inline(always)]
    fn texel_of_hsv(&self, h: u32, s: u32, v: u32) -> Texel {
        let c = &self.classes;
        let achromatic = if v >= c.white_v_min as u32 { WHITE } else { GRAY } as u32;
        let light = if s <= c.achromatic_s_max as u32 { achromatic } else { h };
        let code = if v <= c.black_v_max as u32 { BLACK as u32 } else { light };
        let second = match self.second {
            SecondByte::Saturation => s,
            SecondByte::RawHue => h,
        };
        (code | second << 8) as Texel
    }
}

avx2_multiversion! {
    /// [`TexelRule::rgb_row_chunks`], with AVX2 where the CPU has it.
    fn rgb_row_texels(rule: &TexelRule, rgb: &[u8], out: &mut [Texel]) {
        rule.rgb_row_chunks(rgb, out)
    }
}

avx2_multiversion! {
    /// [`TexelRule::yuyv_row_chunks`], with AVX2 where the CPU has it.
    fn yuyv_row_texels(rule: &TexelRule, yuyv: &[u8], out: &mut [Texel]) {
        rule.yuyv_row_chunks(yuyv, out)
    }
}

/// `floor(x)` as an integer for `0 ≤ x < 2²³`, without a saturating cast (which would
/// keep the loop from vectorising).
#[inline(always)]
fn floor_u32(x: f32) -> u32 {
    const MAGIC: f32 = 8_388_608.0;
    (x.floor() + MAGIC).to_bits() - MAGIC.to_bits()
}

/// [`crate::vision::color::rgb_to_hsv`] on `f32` channel values without branches (same results,
/// bit for bit: the same operations in the same order, selected instead of branched).
#[inline(always)]
fn hsv(r: f32, g: f32, b: f32) -> (u32, u32, u32) {
    let v = r.max(g).max(b);
    let min = r.min(g).min(b);
    let delta = v - min;
    // v ≥ 1 whenever v > 0 (integer channels), so `max(1)` only guards v = 0, where
    // delta = 0 and s = 0 either way.
    let s = 255.0 * delta / v.max(1.0);
    let (vr, vg) = (v == r, v == g);
    let offset = if vr {
        0.0
    } else if vg {
        120.0
    } else {
        240.0
    };
    let num = if vr {
        g - b
    } else if vg {
        b - r
    } else {
        r - g
    };
    let h = offset + 60.0 * num / delta.max(1.0);
    let h = if delta == 0.0 { 0.0 } else { h };
    let h = if h < 0.0 { h + 360.0 } else { h };
    let hq = floor_u32(h / 2.0 + 0.5);
    let hq = if hq >= 180 { hq - 180 } else { hq };
    (hq, floor_u32(s + 0.5), floor_u32(v))
}

/// One camera's texels over a region of its image, row-major, with one ring of
/// [`OUTSIDE_TEXEL`]: image pixel `(u, v)` is texel `(u − origin.0 + 1, v − origin.1 + 1)`.
#[derive(Debug, Clone)]
pub struct LookupImage {
    /// Padded width (region width + 2).
    pub width: usize,
    /// Padded height (region height + 2).
    pub height: usize,
    /// Image pixel of the region's top-left corner.
    pub origin: (usize, usize),
    /// The texels, row-major.
    pub px: Vec<Texel>,
}

impl LookupImage {
    /// Packs the whole of `plane` with `rule`.
    pub fn new(plane: &ColorPlane, rule: &TexelRule) -> Self {
        let (w, h) = (plane.width + 2, plane.height + 2);
        assert!(
            w * h < MAX_TEXELS,
            "{w}x{h} image is larger than the fitness kernel supports"
        );
        let mut px = vec![OUTSIDE_TEXEL; w * h];
        px.par_chunks_exact_mut(w)
            .skip(1)
            .take(plane.height)
            .zip(plane.px.par_chunks_exact(plane.width))
            .for_each(|(row, src)| {
                for (t, c) in row[1..=plane.width].iter_mut().zip(src) {
                    *t = rule.of(c);
                }
            });
        Self {
            width: w,
            height: h,
            origin: (0, 0),
            px,
        }
    }

    /// Converts a whole RGB image (rows on all cores).
    pub fn from_rgb(img: &RgbImage, rule: &TexelRule) -> Self {
        let (w, h) = (img.width() as usize, img.height() as usize);
        let (pw, ph) = (w + 2, h + 2);
        assert!(
            pw * ph < MAX_TEXELS,
            "{pw}x{ph} image is larger than the fitness kernel supports"
        );
        let mut px = vec![OUTSIDE_TEXEL; pw * ph];
        if w > 0 {
            px.par_chunks_exact_mut(pw)
                .skip(1)
                .zip(img.as_raw().par_chunks_exact(3 * w))
                .for_each(|(row, src)| rule.rgb_row(src, &mut row[1..=w]));
        }
        Self {
            width: pw,
            height: ph,
            origin: (0, 0),
            px,
        }
    }

    /// An empty region (every point reads "outside") with room for a whole
    /// `width × height` image, so refills never allocate. The whole capacity is written
    /// once here: its pages are resident from the start, and the loop takes no page
    /// faults on them as the regions move over the image.
    pub fn with_capacity(width: usize, height: usize) -> Self {
        let mut px = vec![OUTSIDE_TEXEL; (width + 2) * (height + 2)];
        px.truncate(4);
        Self {
            width: 2,
            height: 2,
            origin: (0, 0),
            px,
        }
    }

    /// Refills with eye `eye` (0 left, 1 right) of `frame` over `roi` (clipped to the
    /// image); points elsewhere read "outside". Allocates only when `roi` is larger than
    /// any region before (never after [`LookupImage::with_capacity`] for the frame size).
    pub fn refill(&mut self, frame: &SbsBytes, eye: usize, roi: &Region, rule: &TexelRule) {
        let (x0, x1) = (roi.cols.start.min(frame.width), roi.cols.end.min(frame.width));
        let (y0, y1) = (roi.rows.start.min(frame.height), roi.rows.end.min(frame.height));
        let (w, h) = (x1.saturating_sub(x0), y1.saturating_sub(y0));
        self.width = w + 2;
        self.height = h + 2;
        self.origin = (x0, y0);
        self.px.clear();
        self.px.resize(self.width * self.height, OUTSIDE_TEXEL);
        if w == 0 {
            return;
        }
        let rows = (y0..y1).zip(self.px.chunks_exact_mut(self.width).skip(1));
        match frame.format {
            PixelFormat::Rgb8 => {
                for (y, row) in rows {
                    let src = &frame.bytes[y * frame.row_stride + (eye * frame.width + x0) * 3..][..3 * w];
                    rule.rgb_row(src, &mut row[1..=w]);
                }
            }
            PixelFormat::Yuyv => {
                // Pixel pairs share their chroma: an odd first column starts one pixel
                // early, on the ring texel, which is then restored.
                let start = x0 & !1;
                for (y, row) in rows {
                    let out = &mut row[1 + start - x0..=w];
                    let pairs = out.len().div_ceil(2) * 4;
                    let src = &frame.bytes[y * frame.row_stride + (eye * frame.width + start) * 2..][..pairs];
                    rule.yuyv_row(src, out);
                    row[0] = OUTSIDE_TEXEL;
                }
            }
        }
    }
}

/// A side-by-side frame as it arrives (e.g. a shared-memory sample): `height` rows of
/// `row_stride` bytes, eyes of `width` pixels, RGB8 or YUYV.
#[derive(Debug, Clone, Copy)]
pub struct SbsBytes<'a> {
    /// The frame's bytes, `height` rows of `row_stride` bytes.
    pub bytes: &'a [u8],
    /// Width of one eye, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Bytes from one row to the next.
    pub row_stride: usize,
    /// How the pixels are encoded.
    pub format: PixelFormat,
}

impl SbsBytes<'_> {
    /// True when `bytes` holds the whole frame (and, for YUYV, each eye starts on a
    /// whole pixel pair).
    pub fn is_complete(&self) -> bool {
        let row = 2 * self.width * self.format.bytes_per_pixel();
        self.width > 0
            && self.height > 0
            && (self.format == PixelFormat::Rgb8 || self.width.is_multiple_of(2))
            && self.row_stride >= row
            && self.bytes.len() >= self.row_stride * (self.height - 1) + row
    }

    /// The RGB bytes of columns `cols` of row `v` in eye `eye`, for an RGB8 frame that
    /// holds them; `None` otherwise (YUYV, or out of the frame).
    pub fn rgb_row(&self, eye: usize, v: usize, cols: std::ops::Range<usize>) -> Option<&[u8]> {
        if self.format != PixelFormat::Rgb8 || cols.end > self.width || v >= self.height {
            return None;
        }
        let start = v * self.row_stride + (eye * self.width + cols.start) * 3;
        self.bytes.get(start..start + cols.len() * 3)
    }

    /// The RGB of pixel `(u, v)` of eye `eye` (0 left, 1 right; YUYV through
    /// [`yuv_to_rgb`]); `None` outside the image or the bytes.
    pub fn rgb_at(&self, eye: usize, u: usize, v: usize) -> Option<[u8; 3]> {
        if u >= self.width || v >= self.height {
            return None;
        }
        let row = v * self.row_stride;
        match self.format {
            PixelFormat::Rgb8 => {
                let i = row + (eye * self.width + u) * 3;
                let p = self.bytes.get(i..i + 3)?;
                Some([p[0], p[1], p[2]])
            }
            PixelFormat::Yuyv => {
                let i = row + (eye * self.width + (u & !1)) * 2;
                let q = self.bytes.get(i..i + 4)?;
                let (r, g, b) = yuv_to_rgb(if u.is_multiple_of(2) { q[0] } else { q[2] }, q[1], q[3]);
                Some([r, g, b])
            }
        }
    }

    /// Both eyes as RGB images (for a one-shot search over the whole frame; YUYV through
    /// [`yuv_to_rgb`]); `None` when the frame is not complete.
    pub fn to_images(&self) -> Option<StereoImages> {
        if !self.is_complete() {
            return None;
        }
        let (w, h) = (self.width, self.height);
        let row_len = w * self.format.bytes_per_pixel();
        let eye = |e: usize| {
            let mut out = Vec::with_capacity(w * h * 3);
            for y in 0..h {
                let row = &self.bytes[y * self.row_stride + e * row_len..][..row_len];
                match self.format {
                    PixelFormat::Rgb8 => out.extend_from_slice(row),
                    PixelFormat::Yuyv => {
                        for q in row.chunks_exact(4) {
                            for luma in [q[0], q[2]] {
                                let (r, g, b) = yuv_to_rgb(luma, q[1], q[3]);
                                out.extend_from_slice(&[r, g, b]);
                            }
                        }
                    }
                }
            }
            RgbImage::from_raw(w as u32, h as u32, out)
        };
        Some(StereoImages {
            left: eye(0)?,
            right: eye(1)?,
        })
    }
}

/// Both lookup images of one pyramid level, with the level's rig.
#[derive(Debug, Clone)]
pub struct LevelLookup {
    /// Image scale relative to full resolution (1, 1/2, 1/4, …).
    pub scale: f64,
    /// The rig at this level's scale.
    pub rig: StereoRig,
    /// The left camera's lookup image.
    pub left: LookupImage,
    /// The right camera's lookup image.
    pub right: LookupImage,
}

impl LevelLookup {
    /// Whole-image lookups of a pyramid level.
    pub fn new(level: &FrameLevel, rule: &TexelRule) -> Self {
        Self {
            scale: level.scale,
            rig: level.rig.clone(),
            left: LookupImage::new(&level.left, rule),
            right: LookupImage::new(&level.right, rule),
        }
    }

    /// The lookups of every pyramid level of a frame taken with `rig`, level 0 at full
    /// resolution (see [`crate::vision::frame::coarse_levels`]).
    pub fn pyramid(images: &StereoImages, rig: &StereoRig, levels: usize, rule: &TexelRule) -> Vec<Self> {
        Self::pyramid_of(images, &coarse_levels(images, levels), rig, rule)
    }

    /// The lookups of `images` (level 0) and of its already computed `coarse` levels
    /// 1, 2, … (for a caller that needs those images for more than the lookups).
    pub fn pyramid_of(images: &StereoImages, coarse: &[StereoImages], rig: &StereoRig, rule: &TexelRule) -> Vec<Self> {
        let level = |scale: f64, im: &StereoImages| {
            let mut rig = rig.scaled(scale);
            (rig.width, rig.height) = im.eye_size();
            Self {
                scale,
                rig,
                left: LookupImage::from_rgb(&im.left, rule),
                right: LookupImage::from_rgb(&im.right, rule),
            }
        };
        let mut out = vec![level(1.0, images)];
        let mut scale = 1.0;
        for im in coarse {
            scale *= 0.5;
            out.push(level(scale, im));
        }
        out
    }

    /// Full-resolution lookups for `rig`'s image size covering nothing yet (tracking
    /// refills regions of them frame by frame).
    pub fn regions(rig: &StereoRig) -> Self {
        let (w, h) = (rig.width as usize, rig.height as usize);
        Self {
            scale: 1.0,
            rig: rig.clone(),
            left: LookupImage::with_capacity(w, h),
            right: LookupImage::with_capacity(w, h),
        }
    }

    /// Refills both eyes from a frame as it arrived, converting only the pixels of each
    /// eye's region of interest (tracking).
    pub fn refill(&mut self, frame: &SbsBytes, rois: &[Region; 2], rule: &TexelRule) {
        self.left.refill(frame, 0, &rois[0], rule);
        self.right.refill(frame, 1, &rois[1], rule);
    }
}

#[cfg(test)]
mod tests;
