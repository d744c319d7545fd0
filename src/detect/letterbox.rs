//! Letterbox pre-processing: the photo scaled to fit the network input with its aspect
//! kept, centred on gray 114 padding (as YOLO models are trained and exported), and the
//! mapping of boxes between input and photo pixels.

use image::RgbImage;

use super::Rect;

/// The gray of the padding, 0–255.
pub const PAD_GRAY: u8 = 114;

/// Where the scaled photo sits in the network input.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Letterbox {
    /// Photo width, pixels (at least 1).
    pub photo_w: u32,
    /// Photo height, pixels (at least 1).
    pub photo_h: u32,
    /// Network input width, pixels (at least 1).
    pub input_w: u32,
    /// Network input height, pixels (at least 1).
    pub input_h: u32,
    /// Width of the scaled photo inside the input, input pixels.
    pub scaled_w: u32,
    /// Height of the scaled photo inside the input, input pixels.
    pub scaled_h: u32,
    /// Left edge of the scaled photo in the input (padding on the left), input pixels.
    pub pad_x: u32,
    /// Top edge of the scaled photo in the input (padding above), input pixels.
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
    /// NCHW without the batch) scaled to 0..1, resizing it bilinearly with pixel centres
    /// aligned (as OpenCV's `INTER_LINEAR`, which YOLO exports are fed with). `tensor` is
    /// resized to `3 · input_w · input_h` values.
    pub fn fill(&self, photo: &RgbImage, tensor: &mut Vec<f32>) {
        let (iw, ih) = (self.input_w as usize, self.input_h as usize);
        let plane = iw * ih;
        tensor.clear();
        tensor.resize(3 * plane, PAD_GRAY as f32 / 255.0);
        let (pw, ph) = photo.dimensions();
        if pw == 0 || ph == 0 {
            return;
        }
        // Source position of each output column / row: lower index and weight of the upper.
        let taps = |out: u32, src: u32| -> Vec<(usize, usize, f32)> {
            let scale = src as f32 / out as f32;
            (0..out)
                .map(|i| {
                    let x = ((i as f32 + 0.5) * scale - 0.5).clamp(0.0, (src - 1) as f32);
                    let lo = x.floor() as usize;
                    (lo, (lo + 1).min(src as usize - 1), x - lo as f32)
                })
                .collect()
        };
        let columns = taps(self.scaled_w, pw);
        let rows = taps(self.scaled_h, ph);
        let raw = photo.as_raw();
        let stride = pw as usize * 3;
        let (px, py) = (self.pad_x as usize, self.pad_y as usize);
        for (y, &(y0, y1, fy)) in rows.iter().enumerate() {
            let (top, bottom) = (&raw[y0 * stride..][..stride], &raw[y1 * stride..][..stride]);
            let start = (py + y) * iw + px;
            for (x, &(x0, x1, fx)) in columns.iter().enumerate() {
                for c in 0..3 {
                    let at = |row: &[u8], col: usize| row[col * 3 + c] as f32;
                    let upper = at(top, x0) + (at(top, x1) - at(top, x0)) * fx;
                    let lower = at(bottom, x0) + (at(bottom, x1) - at(bottom, x0)) * fx;
                    tensor[c * plane + start + x] = (upper + (lower - upper) * fy) / 255.0;
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
    fn fill_resizes_bilinearly_with_centres_aligned() {
        // A 4 × 1 ramp halved: each output pixel is the mean of two input pixels.
        let mut photo = RgbImage::new(4, 2);
        for (x, v) in [0u8, 100, 200, 250].into_iter().enumerate() {
            photo.put_pixel(x as u32, 0, Rgb([v, v, v]));
            photo.put_pixel(x as u32, 1, Rgb([v, v, v]));
        }
        let lb = Letterbox::new(4, 2, 2, 2);
        assert_eq!((lb.scaled_w, lb.scaled_h, lb.pad_y), (2, 1, 0));
        let mut t = Vec::new();
        lb.fill(&photo, &mut t);
        assert!(
            (t[0] * 255.0 - 50.0).abs() < 1e-3 && (t[1] * 255.0 - 225.0).abs() < 1e-3,
            "{t:?}"
        );
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
