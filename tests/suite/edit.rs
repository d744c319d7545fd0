//! Image edits of the accuracy suite: what the renderer does not do itself. Texture
//! edits (a recoloured or blurred card, same-hue distractors on the wall) happen before
//! rendering; frame edits (white balance, defocus and motion blur) after it, on each eye
//! alone. None of them moves anything, so the truth stays exact.

use image::{Rgb, RgbImage};
use photopose::vision::color::rgb_to_hsv;
use photopose::vision::frame::StereoImages;

/// HSV (OpenCV 8-bit units: H 0..180, S and V 0..=255) → RGB, the inverse of
/// [`rgb_to_hsv`] up to rounding.
pub fn hsv_to_rgb(h: f64, s: f64, v: f64) -> [u8; 3] {
    let h = (h.rem_euclid(180.0)) / 30.0; // sextant 0..6
    let (s, v) = (s.clamp(0.0, 255.0) / 255.0, v.clamp(0.0, 255.0));
    let c = v * s;
    let x = c * (1.0 - (h % 2.0 - 1.0).abs());
    let (r, g, b) = match h as u32 {
        0 => (c, x, 0.0),
        1 => (x, c, 0.0),
        2 => (0.0, c, x),
        3 => (0.0, x, c),
        4 => (x, 0.0, c),
        _ => (c, 0.0, x),
    };
    let m = v - c;
    [r + m, g + m, b + m].map(|u| u.round().clamp(0.0, 255.0) as u8)
}

/// Every pixel's hue shifted by `hue` (OpenCV units) and saturation scaled by `sat`:
/// the same object in another print or under another dye (a category-level difference).
pub fn recolour(image: &RgbImage, hue: f64, sat: f64) -> RgbImage {
    let mut out = image.clone();
    for p in out.pixels_mut() {
        let (h, s, v) = rgb_to_hsv(p[0], p[1], p[2]);
        p.0 = hsv_to_rgb(h as f64 + hue, s as f64 * sat, v as f64);
    }
    out
}

/// Paints the rectangle `[x, y, w, h]` (texels, clipped) of `image` in hue `hue` and
/// saturation `sat`, keeping each pixel's texture as its value (lifted into 70–230 so
/// that the patch stays chromatic): a same-hue recoloured copy of that part of the wall.
pub fn paint_hue(image: &mut RgbImage, [x, y, w, h]: [i64; 4], hue: f64, sat: f64) {
    let (iw, ih) = (image.width() as i64, image.height() as i64);
    for v in y.max(0)..(y + h).min(ih) {
        for u in x.max(0)..(x + w).min(iw) {
            let p = image.get_pixel_mut(u as u32, v as u32);
            let (_, _, value) = rgb_to_hsv(p[0], p[1], p[2]);
            p.0 = hsv_to_rgb(hue, sat, 70.0 + value as f64 * (160.0 / 255.0));
        }
    }
}

/// Per-channel gains `[r, g, b]` on both eyes (a camera white balance off the scene's
/// light), clamped to 0–255.
pub fn white_balance(images: &mut StereoImages, gains: [f64; 3]) {
    for eye in [&mut images.left, &mut images.right] {
        for p in eye.pixels_mut() {
            for (c, g) in p.0.iter_mut().zip(gains) {
                *c = (*c as f64 * g).round().clamp(0.0, 255.0) as u8;
            }
        }
    }
}

/// Gaussian blur of standard deviation `sigma` px on each eye (defocus).
pub fn defocus(images: &mut StereoImages, sigma: f32) {
    images.left = image::imageops::blur(&images.left, sigma);
    images.right = image::imageops::blur(&images.right, sigma);
}

/// Motion blur on each eye: the mean of the image shifted along `dir` (pixels, any
/// length) over a centred stroke of `length` px, bilinearly sampled, edges clamped.
pub fn motion(images: &mut StereoImages, length: f64, dir: [f64; 2]) {
    let n = (length.ceil() as usize).max(1) * 2 + 1;
    let norm = (dir[0].hypot(dir[1])).max(1e-12);
    let step = [dir[0] / norm, dir[1] / norm];
    let offsets: Vec<[f64; 2]> = (0..n)
        .map(|i| {
            let t = length * (i as f64 / (n - 1) as f64 - 0.5);
            [t * step[0], t * step[1]]
        })
        .collect();
    images.left = smear(&images.left, &offsets);
    images.right = smear(&images.right, &offsets);
}

/// The mean of `image` sampled at each pixel plus each of `offsets`.
fn smear(image: &RgbImage, offsets: &[[f64; 2]]) -> RgbImage {
    let (w, h) = image.dimensions();
    RgbImage::from_fn(w, h, |x, y| {
        let mut acc = [0.0; 3];
        for [dx, dy] in offsets {
            let c = bilinear(image, x as f64 + dx, y as f64 + dy);
            for k in 0..3 {
                acc[k] += c[k];
            }
        }
        Rgb(acc.map(|a| (a / offsets.len() as f64).round().clamp(0.0, 255.0) as u8))
    })
}

/// `image` at `(x, y)` (pixel centres at integers), bilinear, edges clamped.
fn bilinear(image: &RgbImage, x: f64, y: f64) -> [f64; 3] {
    let (w, h) = (image.width() as i64 - 1, image.height() as i64 - 1);
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let at = |u: f64, v: f64| {
        image
            .get_pixel((u as i64).clamp(0, w) as u32, (v as i64).clamp(0, h) as u32)
            .0
    };
    let (a, b, c, d) = (at(x0, y0), at(x0 + 1.0, y0), at(x0, y0 + 1.0), at(x0 + 1.0, y0 + 1.0));
    std::array::from_fn(|k| {
        let top = a[k] as f64 * (1.0 - fx) + b[k] as f64 * fx;
        let bottom = c[k] as f64 * (1.0 - fx) + d[k] as f64 * fx;
        top * (1.0 - fy) + bottom * fy
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hsv_round_trips_through_opencv_units() {
        for rgb in [
            [200, 40, 30],
            [30, 180, 90],
            [20, 60, 220],
            [128, 128, 128],
            [250, 240, 10],
        ] {
            let (h, s, v) = rgb_to_hsv(rgb[0], rgb[1], rgb[2]);
            let back = hsv_to_rgb(h as f64, s as f64, v as f64);
            for k in 0..3 {
                assert!(back[k].abs_diff(rgb[k]) <= 4, "{rgb:?} → {:?} → {back:?}", (h, s, v));
            }
        }
    }

    #[test]
    fn recolour_shifts_hue_and_scales_saturation() {
        let img = RgbImage::from_pixel(2, 2, Rgb([200, 60, 40]));
        let (h0, s0, _) = rgb_to_hsv(200, 60, 40);
        let p = recolour(&img, 8.0, 0.8).get_pixel(0, 0).0;
        let (h1, s1, _) = rgb_to_hsv(p[0], p[1], p[2]);
        assert!((h1 as i32 - h0 as i32 - 8).abs() <= 1, "hue {h0} → {h1}");
        assert!((s1 as f64 - 0.8 * s0 as f64).abs() <= 3.0, "saturation {s0} → {s1}");
    }

    #[test]
    fn frame_edits_keep_a_flat_image_flat_and_move_nothing() {
        let mut images = StereoImages {
            left: RgbImage::from_fn(9, 9, |x, _| Rgb([if x == 4 { 255 } else { 0 }; 3])),
            right: RgbImage::from_pixel(9, 9, Rgb([100, 100, 100])),
        };
        motion(&mut images, 2.0, [1.0, 0.0]);
        let row: Vec<u8> = (0..9).map(|x| images.left.get_pixel(x, 4)[0]).collect();
        assert_eq!(row[3], row[5], "symmetric stroke: {row:?}");
        assert!(row[4] > row[3] && row[3] > 0 && row[1] == 0, "{row:?}");
        white_balance(&mut images, [1.15, 1.0, 0.85]);
        assert_eq!(images.right.get_pixel(4, 4).0, [115, 100, 85]);
    }
}
