//! Lookup images: what the fitness reads per pixel (colour code, saturation and the
//! outer-point verdict) packed into one `u32`, with a ring of outside texels around the
//! image. The kernel clamps a projected point onto the padded image instead of branching
//! on whether it is inside: a point off the image lands on the ring and reads "outside".

use rayon::prelude::*;

use crate::camera::StereoRig;
use crate::color::{rgb_to_hsv, ColorClasses};
use crate::frame::{ColorPlane, FrameLevel, PixelColor, Region};

/// Colour code of a texel outside the image: it matches no model colour and, for outer
/// points, counts as target (a mismatch), as points outside an image do.
pub const OUTSIDE: u8 = 255;

/// What the fitness reads per pixel, packed in one `u32`: bits 0–7 the [`crate::color`]
/// code (or [`OUTSIDE`]), bits 8–15 the saturation, bit 16 ([`TARGET_BIT`]) set when an
/// outer point on this pixel sees the target (eq. 16's `e4` case).
pub type Texel = u32;

/// Bit of [`Texel`] marking a pixel that looks like the target to an outer point.
pub const TARGET_BIT: Texel = 1 << 16;

/// Packs a pixel's colour code, saturation and outer-point verdict.
pub fn texel(code: u8, sat: u8, target: bool) -> Texel {
    code as Texel | (sat as Texel) << 8 | if target { TARGET_BIT } else { 0 }
}

/// The texel of the ring around the image.
pub const OUTSIDE_TEXEL: Texel = OUTSIDE as Texel | TARGET_BIT;

/// The fitness kernel computes indices in `f32` and rounds with the 2²³ trick, so a
/// padded image holds fewer texels than this (2K has 2.7 M).
pub const MAX_TEXELS: usize = 1 << 23;

/// One camera's texels, row-major, with one ring of [`OUTSIDE_TEXEL`]: image pixel
/// `(u, v)` is texel `(u + 1, v + 1)`.
#[derive(Debug, Clone)]
pub struct LookupImage {
    /// Padded size (image size + 2).
    pub width: usize,
    pub height: usize,
    pub px: Vec<Texel>,
}

impl LookupImage {
    /// Packs `plane`; `target` decides each pixel's outer-point verdict.
    pub fn new(plane: &ColorPlane, target: impl Fn(&PixelColor) -> bool + Sync) -> Self {
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
                    *t = texel(c.code, c.sat, target(c));
                }
            });
        Self {
            width: w,
            height: h,
            px,
        }
    }
}

/// A side-by-side RGB8 frame as it arrives (e.g. a shared-memory sample): `height` rows
/// of `row_stride` bytes, eyes of `width` pixels.
#[derive(Debug, Clone, Copy)]
pub struct SbsBytes<'a> {
    pub bytes: &'a [u8],
    pub width: usize,
    pub height: usize,
    pub row_stride: usize,
}

impl SbsBytes<'_> {
    /// True when `bytes` holds the whole frame.
    pub fn is_complete(&self) -> bool {
        let row = 2 * self.width * 3;
        self.width > 0
            && self.height > 0
            && self.row_stride >= row
            && self.bytes.len() >= self.row_stride * (self.height - 1) + row
    }
}

impl LookupImage {
    /// An image of outside texels for `width × height` pixels.
    pub fn outside(width: usize, height: usize) -> Self {
        let (w, h) = (width + 2, height + 2);
        Self {
            width: w,
            height: h,
            px: vec![OUTSIDE_TEXEL; w * h],
        }
    }

    /// Refills from eye `eye` (0 left, 1 right) of `frame`, converting only the pixels in
    /// `roi`; every other texel reads "outside". Allocates only when the size changes.
    pub fn refill(
        &mut self,
        frame: &SbsBytes,
        eye: usize,
        roi: &Region,
        classes: &ColorClasses,
        target: impl Fn(&PixelColor) -> bool,
    ) {
        if self.width != frame.width + 2 || self.height != frame.height + 2 {
            *self = Self::outside(frame.width, frame.height);
        } else {
            self.px.fill(OUTSIDE_TEXEL);
        }
        let (x0, x1) = (roi.cols.start.min(frame.width), roi.cols.end.min(frame.width));
        for y in roi.rows.start..roi.rows.end.min(frame.height) {
            let src = &frame.bytes[y * frame.row_stride + (eye * frame.width + x0) * 3..];
            let dst = &mut self.px[(y + 1) * self.width + 1 + x0..];
            for (t, p) in dst[..x1.saturating_sub(x0)].iter_mut().zip(src.chunks_exact(3)) {
                let (hue, sat, v) = rgb_to_hsv(p[0], p[1], p[2]);
                let c = PixelColor {
                    code: classes.code(hue, sat, v),
                    sat,
                    hue,
                };
                *t = texel(c.code, c.sat, target(&c));
            }
        }
    }
}

/// Both lookup images of one pyramid level, with the level's rig.
#[derive(Debug, Clone)]
pub struct LevelLookup {
    /// Image scale relative to full resolution (1, 1/2, 1/4, …).
    pub scale: f64,
    pub rig: StereoRig,
    pub left: LookupImage,
    pub right: LookupImage,
}

impl LevelLookup {
    pub fn new(level: &FrameLevel, target: impl Fn(&PixelColor) -> bool + Sync) -> Self {
        Self {
            scale: level.scale,
            rig: level.rig.clone(),
            left: LookupImage::new(&level.left, &target),
            right: LookupImage::new(&level.right, &target),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn image_is_framed_by_outside_texels() {
        let plane = ColorPlane {
            width: 3,
            height: 2,
            px: (0..6)
                .map(|i| PixelColor {
                    code: i as u8,
                    sat: 10 * i as u8,
                    hue: 0,
                })
                .collect(),
        };
        let img = LookupImage::new(&plane, |c| c.code % 2 == 1);
        assert_eq!((img.width, img.height), (5, 4));
        assert!(img.px[..5].iter().all(|&t| t == OUTSIDE_TEXEL));
        assert!(img.px[15..].iter().all(|&t| t == OUTSIDE_TEXEL));
        assert_eq!([img.px[5], img.px[9]], [OUTSIDE_TEXEL; 2]);
        // Pixel (2, 1) is texel (3, 2): code 5, saturation 50, target.
        assert_eq!(img.px[2 * 5 + 3], 5 | 50 << 8 | TARGET_BIT);
        assert_eq!(img.px[5 + 1], 0);
    }
}
