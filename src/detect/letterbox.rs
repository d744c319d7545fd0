//! Letterbox pre-processing: the photo scaled to fit the network input with its aspect
//! kept, centred on gray 114 padding (as YOLO models are trained and exported), and the
//! mapping of boxes between input and photo pixels.

use image::imageops::{self, FilterType};
use image::RgbImage;

use super::Rect;

/// The gray of the padding, 0–255.
pub const PAD_GRAY: u8 = 114;

/// Where the scaled photo sits in the network input.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Letterbox {
    pub photo_w: u32,
    pub photo_h: u32,
    pub input_w: u32,
    pub input_h: u32,
    /// Size of the scaled photo inside the input.
    pub scaled_w: u32,
    pub scaled_h: u32,
    /// Top-left corner of the scaled photo in the input.
    pub pad_x: u32,
    pub pad_y: u32,
}

impl Letterbox {
    /// The placement of a `photo_w × photo_h` photo in an `input_w × input_h` input (all ≥ 1).
    pub fn new(photo_w: u32, photo_h: u32, input_w: u32, input_h: u32) -> Self {
        let (pw, ph) = (photo_w.max(1), photo_h.max(1));
        let (iw, ih) = (input_w.max(1), input_h.max(1));
        let scale = (iw as f64 / pw as f64).min(ih as f64 / ph as f64);
        let scaled_w = ((pw as f64 * scale).round() as u32).clamp(1, iw);
        let scaled_h = ((ph as f64 * scale).round() as u32).clamp(1, ih);
        Self {
            photo_w: pw,
            photo_h: ph,
            input_w: iw,
            input_h: ih,
            scaled_w,
            scaled_h,
            pad_x: (iw - scaled_w) / 2,
            pad_y: (ih - scaled_h) / 2,
        }
    }

    /// Input pixels per photo pixel along x and y (equal up to rounding).
    pub fn scale(&self) -> (f32, f32) {
        (
            self.scaled_w as f32 / self.photo_w as f32,
            self.scaled_h as f32 / self.photo_h as f32,
        )
    }

    /// A box in input pixels → photo pixels, clipped to the photo.
    pub fn to_photo(&self, r: &Rect) -> Rect {
        let (sx, sy) = self.scale();
        let (px, py) = (self.pad_x as f32, self.pad_y as f32);
        let (w, h) = (self.photo_w as f32, self.photo_h as f32);
        Rect {
            x0: ((r.x0 - px) / sx).clamp(0.0, w),
            y0: ((r.y0 - py) / sy).clamp(0.0, h),
            x1: ((r.x1 - px) / sx).clamp(0.0, w),
            y1: ((r.y1 - py) / sy).clamp(0.0, h),
        }
    }

    /// A box in photo pixels → input pixels.
    pub fn to_input(&self, r: &Rect) -> Rect {
        let (sx, sy) = self.scale();
        let (px, py) = (self.pad_x as f32, self.pad_y as f32);
        Rect {
            x0: r.x0 * sx + px,
            y0: r.y0 * sy + py,
            x1: r.x1 * sx + px,
            y1: r.y1 * sy + py,
        }
    }

    /// Writes the letterboxed photo into `tensor` as planar RGB (`[3, input_h, input_w]`,
    /// NCHW without the batch) scaled to 0..1. `tensor` must hold `3 · input_w · input_h`
    /// values; it is resized if not.
    pub fn fill(&self, photo: &RgbImage, tensor: &mut Vec<f32>) {
        let (iw, ih) = (self.input_w as usize, self.input_h as usize);
        let plane = iw * ih;
        tensor.clear();
        tensor.resize(3 * plane, PAD_GRAY as f32 / 255.0);
        let scaled;
        let src = if photo.dimensions() == (self.scaled_w, self.scaled_h) {
            photo
        } else {
            scaled = imageops::resize(photo, self.scaled_w, self.scaled_h, FilterType::Triangle);
            &scaled
        };
        let (px, py) = (self.pad_x as usize, self.pad_y as usize);
        for (y, row) in src.rows().enumerate() {
            let start = (py + y) * iw + px;
            for (x, p) in row.enumerate() {
                for c in 0..3 {
                    tensor[c * plane + start + x] = p.0[c] as f32 / 255.0;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::Rgb;

    #[test]
    fn wide_photo_is_centred_vertically() {
        let lb = Letterbox::new(600, 400, 416, 416);
        assert_eq!((lb.scaled_w, lb.scaled_h), (416, 277));
        assert_eq!((lb.pad_x, lb.pad_y), (0, 69));
        let tall = Letterbox::new(300, 600, 640, 640);
        assert_eq!(
            (tall.scaled_w, tall.scaled_h, tall.pad_x, tall.pad_y),
            (320, 640, 160, 0)
        );
    }

    #[test]
    fn boxes_round_trip_between_photo_and_input() {
        for (pw, ph, iw, ih) in [
            (600, 400, 416, 416),
            (400, 600, 640, 640),
            (1280, 720, 640, 384),
            (50, 50, 64, 64),
        ] {
            let lb = Letterbox::new(pw, ph, iw, ih);
            let r = Rect {
                x0: 0.1 * pw as f32,
                y0: 0.2 * ph as f32,
                x1: 0.7 * pw as f32,
                y1: 0.9 * ph as f32,
            };
            let back = lb.to_photo(&lb.to_input(&r));
            for (a, b) in [(r.x0, back.x0), (r.y0, back.y0), (r.x1, back.x1), (r.y1, back.y1)] {
                assert!((a - b).abs() < 1e-3, "{pw}x{ph} in {iw}x{ih}: {r:?} → {back:?}");
            }
            // The photo's corners land on the scaled photo's corners in the input.
            let whole = lb.to_input(&Rect {
                x0: 0.0,
                y0: 0.0,
                x1: pw as f32,
                y1: ph as f32,
            });
            assert!((whole.x0 - lb.pad_x as f32).abs() < 1e-3 && (whole.y0 - lb.pad_y as f32).abs() < 1e-3);
            assert!((whole.x1 - (lb.pad_x + lb.scaled_w) as f32).abs() < 1e-3);
            assert!((whole.y1 - (lb.pad_y + lb.scaled_h) as f32).abs() < 1e-3);
        }
    }

    #[test]
    fn boxes_in_the_padding_are_clipped_to_the_photo() {
        let lb = Letterbox::new(600, 400, 416, 416);
        let r = lb.to_photo(&Rect {
            x0: -10.0,
            y0: 0.0,
            x1: 500.0,
            y1: 416.0,
        });
        assert_eq!((r.x0, r.y0, r.x1, r.y1), (0.0, 0.0, 600.0, 400.0));
    }

    #[test]
    fn fill_pads_with_gray_and_keeps_colours() {
        let photo = RgbImage::from_pixel(20, 10, Rgb([255, 0, 51]));
        let lb = Letterbox::new(20, 10, 32, 32);
        let mut t = Vec::new();
        lb.fill(&photo, &mut t);
        assert_eq!(t.len(), 3 * 32 * 32);
        assert_eq!((lb.scaled_w, lb.scaled_h, lb.pad_x, lb.pad_y), (32, 16, 0, 8));
        let at = |c: usize, x: usize, y: usize| t[c * 32 * 32 + y * 32 + x];
        let gray = PAD_GRAY as f32 / 255.0;
        assert_eq!((at(0, 5, 2), at(1, 5, 2), at(2, 5, 30)), (gray, gray, gray));
        assert!((at(0, 16, 16) - 1.0).abs() < 1e-6);
        assert!(at(1, 16, 16).abs() < 1e-6);
        assert!((at(2, 16, 16) - 0.2).abs() < 1e-6);
    }
}
