//! The left eye, shrunk for the viewer: box-averaged by a whole factor so it is at most
//! a given width.

use image::RgbImage;

use crate::vision::color::yuv_to_rgb;
use crate::vision::lookup::SbsBytes;
use crate::vision::PixelFormat;

/// The whole factor that brings `width` pixels of `format` to at most `max_width` (at
/// least 1; even for YUYV, so that blocks hold whole pixel pairs).
pub fn factor(width: usize, max_width: usize, format: PixelFormat) -> usize {
    let step = width.div_ceil(max_width.max(1)).max(1);
    match format {
        PixelFormat::Yuyv => step.next_multiple_of(2),
        PixelFormat::Rgb8 => step,
    }
}

/// A `width` × `height` image of `format` rows (`row(y)`) shrunk by `step`: each pixel
/// the mean of a `step` × `step` block (YUYV averaged before it becomes RGB). The rows of
/// a block are summed byte by byte first (which vectorises), then each block across: it
/// runs beside the estimator, so it must be cheap.
fn shrink<'a>(
    width: usize,
    height: usize,
    step: usize,
    format: PixelFormat,
    row: impl Fn(usize) -> &'a [u8],
) -> RgbImage {
    let (w, h) = (width / step, height / step);
    let used = w * step * format.bytes_per_pixel();
    let n = (step * step) as u32;
    let mean = |s: u32| ((s + n / 2) / n) as u8;
    let mut columns = vec![0u32; used];
    let mut out = Vec::with_capacity(w * h * 3);
    for by in 0..h {
        columns.fill(0);
        for y in by * step..(by + 1) * step {
            for (c, &b) in columns.iter_mut().zip(&row(y)[..used]) {
                *c += u32::from(b);
            }
        }
        for block in columns.chunks_exact(step * format.bytes_per_pixel()) {
            let s = block_sum(block, format).map(mean);
            let rgb = match format {
                PixelFormat::Rgb8 => s,
                PixelFormat::Yuyv => {
                    let (r, g, b) = yuv_to_rgb(s[0], s[1], s[2]);
                    [r, g, b]
                }
            };
            out.extend(rgb);
        }
    }
    RgbImage::from_raw(w as u32, h as u32, out).unwrap_or_default()
}

/// R, G, B (or Y, U, V) summed over the pixels of one block's column sums.
fn block_sum(block: &[u32], format: PixelFormat) -> [u32; 3] {
    match format {
        PixelFormat::Rgb8 => block
            .chunks_exact(3)
            .fold([0; 3], |a, p| [a[0] + p[0], a[1] + p[1], a[2] + p[2]]),
        PixelFormat::Yuyv => block
            .chunks_exact(4)
            .fold([0; 3], |a, q| [a[0] + q[0] + q[2], a[1] + 2 * q[1], a[2] + 2 * q[3]]),
    }
}

/// The left eye of a side-by-side frame shrunk by `step` (a [`factor`]); `None` when the
/// frame is not complete or `step` does not suit its format.
pub fn left_eye(frame: &SbsBytes, step: usize) -> Option<RgbImage> {
    let whole_pairs = frame.format == PixelFormat::Rgb8 || step.is_multiple_of(2);
    if !frame.is_complete() || step == 0 || !whole_pairs {
        return None;
    }
    let row = |y: usize| &frame.bytes[y * frame.row_stride..];
    Some(shrink(frame.width, frame.height, step, frame.format, row))
}

/// An RGB image shrunk by `step` (a copy for 1).
pub fn shrink_rgb(img: &RgbImage, step: usize) -> RgbImage {
    if step <= 1 {
        return img.clone();
    }
    let w = img.width() as usize * 3;
    let raw = img.as_raw();
    shrink(
        img.width() as usize,
        img.height() as usize,
        step,
        PixelFormat::Rgb8,
        |y| &raw[y * w..],
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vision::color::rgb_row_to_yuyv;

    /// A side-by-side RGB frame whose left eye is a horizontal ramp, right eye black.
    fn sbs(width: usize, height: usize) -> Vec<u8> {
        let mut rgb = vec![0u8; 2 * width * height * 3];
        for y in 0..height {
            for x in 0..width {
                let v = (x * 255 / (width - 1)) as u8;
                rgb[(y * 2 * width + x) * 3..][..3].copy_from_slice(&[v, v, v]);
            }
        }
        rgb
    }

    #[test]
    fn the_left_eye_is_averaged_in_blocks_from_rgb_and_yuyv() {
        let (w, h) = (8, 4);
        let rgb = sbs(w, h);
        let frame = SbsBytes {
            bytes: &rgb,
            width: w,
            height: h,
            row_stride: 2 * w * 3,
            format: PixelFormat::Rgb8,
        };
        let small = left_eye(&frame, 2).unwrap();
        assert_eq!(small.dimensions(), (4, 2));
        // Columns 0 and 1 of the ramp: 0 and 36, mean 18.
        assert_eq!(small.get_pixel(0, 0).0, [18, 18, 18]);
        assert_eq!(small.get_pixel(3, 1).0, [237, 237, 237]);
        let mut yuyv = vec![0u8; rgb.len() / 3 * 2];
        for (src, dst) in rgb.chunks_exact(2 * w * 3).zip(yuyv.chunks_exact_mut(2 * w * 2)) {
            rgb_row_to_yuyv(src, dst);
        }
        let frame = SbsBytes {
            bytes: &yuyv,
            row_stride: 2 * w * 2,
            format: PixelFormat::Yuyv,
            ..frame
        };
        let small_yuyv = left_eye(&frame, 2).unwrap();
        assert_eq!(small_yuyv.dimensions(), (4, 2));
        let diff = |a: u8, b: u8| a.abs_diff(b);
        assert!(
            diff(small_yuyv.get_pixel(3, 1).0[0], 237) <= 3,
            "{:?}",
            small_yuyv.get_pixel(3, 1)
        );
        // A short payload is no frame; an odd factor splits YUYV pairs.
        let short = SbsBytes {
            bytes: &yuyv[..10],
            ..frame
        };
        assert!(left_eye(&short, 2).is_none());
        assert!(left_eye(&frame, 3).is_none());
    }

    #[test]
    fn factor_fits_the_width_and_odd_factors_shrink_whole_blocks() {
        let rgb = |w| factor(w, 640, PixelFormat::Rgb8);
        assert_eq!((rgb(1280), rgb(1920), rgb(2208), rgb(100)), (2, 3, 4, 1));
        assert_eq!(factor(1920, 640, PixelFormat::Yuyv), 4, "whole YUYV pairs");
        let mut img = RgbImage::from_pixel(7, 6, image::Rgb([200, 10, 10]));
        img.put_pixel(2, 2, image::Rgb([20, 10, 10]));
        let small = shrink_rgb(&img, 3);
        // Whole 3 × 3 blocks only; (2, 2) pulls its block's mean down by 20.
        assert_eq!(small.dimensions(), (2, 2));
        assert_eq!(small.get_pixel(0, 0).0, [180, 10, 10]);
        assert_eq!(small.get_pixel(1, 1).0, [200, 10, 10]);
        assert_eq!(shrink_rgb(&img, 1), img);
    }
}
