//! Colour handling of the paper's Table 1: OpenCV 8-bit HSV and the four colour classes
//! (black, gray, white, other), packed into one byte per pixel or sample point.

/// Class code of a black pixel (any hue or saturation, dark).
pub const BLACK: u8 = 252;
/// Class code of a gray pixel (low saturation, mid value).
pub const GRAY: u8 = 253;
/// Class code of a white pixel (low saturation, bright).
pub const WHITE: u8 = 254;

/// Thresholds of Table 1 (OpenCV ranges: H 0–180, S and V 0–255).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ColorClasses {
    /// `V ≤ black_v_max` is black (paper: 45).
    pub black_v_max: u8,
    /// `S ≤ achromatic_s_max` (and not black) is gray or white (paper: 30).
    pub achromatic_s_max: u8,
    /// An achromatic pixel with `V ≥ white_v_min` is white, else gray (paper: 221).
    pub white_v_min: u8,
}

impl Default for ColorClasses {
    fn default() -> Self {
        Self {
            black_v_max: 45,
            achromatic_s_max: 30,
            white_v_min: 221,
        }
    }
}

impl ColorClasses {
    /// The colour code of an HSV triple: the hue `0..180` for a chromatic colour
    /// ("other" in Table 1), or [`BLACK`], [`GRAY`], [`WHITE`].
    #[inline]
    pub fn code(&self, h: u8, s: u8, v: u8) -> u8 {
        if v <= self.black_v_max {
            BLACK
        } else if s <= self.achromatic_s_max {
            if v >= self.white_v_min {
                WHITE
            } else {
                GRAY
            }
        } else {
            h
        }
    }
}

/// True when a colour code is a hue (Table 1's "other colours").
#[inline]
pub fn is_chromatic(code: u8) -> bool {
    code < 180
}

/// Distance between two OpenCV hues on the 180-step colour circle.
///
/// ```
/// use photopose::vision::color::{hue_distance, rgb_to_hsv};
/// let (red, _, _) = rgb_to_hsv(255, 0, 10); // hue 179, just below the wrap
/// assert_eq!(hue_distance(red, 2), 3);
/// ```
#[inline]
pub fn hue_distance(a: u8, b: u8) -> u8 {
    let d = a.abs_diff(b);
    d.min(180 - d.min(180))
}

/// RGB → HSV exactly as OpenCV's `COLOR_RGB2HSV` for 8-bit images
/// (H = degrees / 2 in 0..180, S and V in 0..=255, hue 0 where max = min).
#[inline]
pub fn rgb_to_hsv(r: u8, g: u8, b: u8) -> (u8, u8, u8) {
    let (rf, gf, bf) = (r as f32, g as f32, b as f32);
    let v = rf.max(gf).max(bf);
    let min = rf.min(gf).min(bf);
    let delta = v - min;
    let s = if v > 0.0 { 255.0 * delta / v } else { 0.0 };
    let h = if delta == 0.0 {
        0.0
    } else if v == rf {
        60.0 * (gf - bf) / delta
    } else if v == gf {
        120.0 + 60.0 * (bf - rf) / delta
    } else {
        240.0 + 60.0 * (rf - gf) / delta
    };
    let h = if h < 0.0 { h + 360.0 } else { h };
    // `x + 0.5` truncated is `round` for non-negative x, without a libm call.
    let h = ((h / 2.0 + 0.5) as u32 % 180) as u8;
    (h, (s + 0.5) as u8, v as u8)
}

/// Fixed-point BT.601 coefficients of YUV → RGB (limited range: Y 16–235, U and V
/// 16–240 around 128), scaled by 2²⁰ as in OpenCV's `COLOR_YUV2RGB_YUYV`.
pub mod bt601 {
    /// Fixed-point fraction bits: the coefficients are scaled by `1 << SHIFT`.
    pub const SHIFT: i32 = 20;
    /// Luma gain 1.164 on `Y − 16` (all channels).
    pub const CY: i32 = 1_220_542;
    /// `U − 128` → blue, 2.018.
    pub const CUB: i32 = 2_116_026;
    /// `U − 128` → green, −0.391.
    pub const CUG: i32 = -409_993;
    /// `V − 128` → green, −0.813.
    pub const CVG: i32 = -852_492;
    /// `V − 128` → red, 1.596.
    pub const CVR: i32 = 1_673_527;
    /// Rounding term added before the shift.
    pub const HALF: i32 = 1 << (SHIFT - 1);
}

/// One pixel of a UVC YUYV image (its luma `y` and the chroma `u`, `v` it shares with its
/// neighbour) as RGB: BT.601, limited range, rounded and saturated.
#[inline]
pub fn yuv_to_rgb(y: u8, u: u8, v: u8) -> (u8, u8, u8) {
    use bt601::*;
    let (uu, vv) = (u as i32 - 128, v as i32 - 128);
    let yy = (y as i32 - 16).max(0) * CY;
    let channel = |c: i32| ((yy + HALF + c) >> SHIFT).clamp(0, 255) as u8;
    (channel(CVR * vv), channel(CVG * vv + CUG * uu), channel(CUB * uu))
}

/// RGB → BT.601 limited-range `(Y, U, V)`, rounded: what a UVC camera sends for a colour
/// (the inverse of [`yuv_to_rgb`] up to rounding).
#[inline]
pub fn rgb_to_yuv(r: u8, g: u8, b: u8) -> (u8, u8, u8) {
    let (r, g, b) = (r as f32, g as f32, b as f32);
    let y = 16.0 + (65.481 * r + 128.553 * g + 24.966 * b) / 255.0;
    let u = 128.0 + (-37.797 * r - 74.203 * g + 112.0 * b) / 255.0;
    let v = 128.0 + (112.0 * r - 93.786 * g - 18.214 * b) / 255.0;
    let q = |x: f32| (x + 0.5).clamp(0.0, 255.0) as u8;
    (q(y), q(u), q(v))
}

/// Encodes a row of RGB8 pixels (an even number) as YUYV, each pair sharing the mean of
/// its two pixels' chroma, as a 4:2:2 camera does.
pub fn rgb_row_to_yuyv(rgb: &[u8], yuyv: &mut [u8]) {
    for (p, q) in rgb.chunks_exact(6).zip(yuyv.chunks_exact_mut(4)) {
        let (y0, u0, v0) = rgb_to_yuv(p[0], p[1], p[2]);
        let (y1, u1, v1) = rgb_to_yuv(p[3], p[4], p[5]);
        let mean = |a: u8, b: u8| (a as u16 + b as u16).div_ceil(2) as u8;
        q.copy_from_slice(&[y0, mean(u0, u1), y1, mean(v0, v1)]);
    }
}

/// A side-by-side RGB8 frame (both eyes `eye_width` pixels wide, rows back to back)
/// encoded as the ZED sends it: YUYV, two bytes a pixel (a last partial row is left
/// out; no rows for a width of 0).
pub fn yuyv_from_rgb(rgb: &[u8], eye_width: usize) -> Vec<u8> {
    let row = 2 * eye_width;
    if row == 0 {
        return Vec::new();
    }
    let mut yuyv = vec![0u8; rgb.len() / (3 * row) * 2 * row];
    for (src, dst) in rgb.chunks_exact(3 * row).zip(yuyv.chunks_exact_mut(2 * row)) {
        rgb_row_to_yuyv(src, dst);
    }
    yuyv
}

/// Circular mean of OpenCV hues; `None` for an empty set or hues that cancel out.
pub fn circular_mean_hue(hues: impl IntoIterator<Item = u8>) -> Option<f64> {
    let (mut sx, mut sy, mut n) = (0.0f64, 0.0f64, 0usize);
    for h in hues {
        let a = h as f64 * std::f64::consts::PI / 90.0;
        sx += a.cos();
        sy += a.sin();
        n += 1;
    }
    if n == 0 || (sx * sx + sy * sy).sqrt() < 1e-6 * n as f64 {
        return None;
    }
    let deg = sy.atan2(sx).to_degrees();
    Some((if deg < 0.0 { deg + 360.0 } else { deg }) / 2.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hsv_matches_opencv_reference_values() {
        // Values from cv2.cvtColor(np.uint8([[[r, g, b]]]), cv2.COLOR_RGB2HSV).
        assert_eq!(rgb_to_hsv(255, 0, 0), (0, 255, 255));
        assert_eq!(rgb_to_hsv(0, 255, 0), (60, 255, 255));
        assert_eq!(rgb_to_hsv(0, 0, 255), (120, 255, 255));
        assert_eq!(rgb_to_hsv(255, 255, 0), (30, 255, 255));
        assert_eq!(rgb_to_hsv(128, 128, 128), (0, 0, 128));
        assert_eq!(rgb_to_hsv(200, 100, 50), (10, 191, 200));
        assert_eq!(rgb_to_hsv(50, 100, 200), (110, 191, 200));
        assert_eq!(rgb_to_hsv(255, 0, 128), (165, 255, 255));
        assert_eq!(rgb_to_hsv(0, 0, 0), (0, 0, 0));
    }

    #[test]
    fn yuv_converts_as_bt601_limited_range() {
        // Black, white, gray, then 75 % colour bars (191 = 0.75 · 255 within the
        // rounding of their tabulated Y'CbCr).
        assert_eq!(yuv_to_rgb(16, 128, 128), (0, 0, 0));
        assert_eq!(yuv_to_rgb(235, 128, 128), (255, 255, 255));
        assert_eq!(yuv_to_rgb(126, 128, 128), (128, 128, 128));
        assert_eq!(yuv_to_rgb(0, 128, 128), (0, 0, 0));
        assert_eq!(yuv_to_rgb(255, 128, 128), (255, 255, 255));
        assert_eq!(yuv_to_rgb(65, 100, 212), (191, 0, 1));
        assert_eq!(yuv_to_rgb(112, 72, 58), (0, 191, 0));
        assert_eq!(yuv_to_rgb(35, 212, 114), (0, 1, 192));
        assert_eq!(yuv_to_rgb(162, 44, 142), (192, 191, 0));
        // Saturation at both ends.
        assert_eq!(yuv_to_rgb(235, 255, 0), (51, 255, 255));
        assert_eq!(yuv_to_rgb(16, 0, 255), (203, 0, 0));
    }

    #[test]
    fn yuv_round_trips_within_rounding() {
        for (r, g, b) in [
            (0, 0, 0),
            (255, 255, 255),
            (200, 100, 50),
            (50, 100, 200),
            (255, 0, 128),
        ] {
            let (y, u, v) = rgb_to_yuv(r, g, b);
            let back = yuv_to_rgb(y, u, v);
            for (a, b) in [(back.0, r), (back.1, g), (back.2, b)] {
                assert!(a.abs_diff(b) <= 2, "{:?} -> {:?}", (r, g, b), back);
            }
        }
        let mut yuyv = [0u8; 4];
        rgb_row_to_yuyv(&[255, 0, 0, 0, 0, 255], &mut yuyv);
        let (red, blue) = (rgb_to_yuv(255, 0, 0), rgb_to_yuv(0, 0, 255));
        assert_eq!(yuyv[0], red.0);
        assert_eq!(yuyv[2], blue.0);
        assert_eq!(yuyv[1], (red.1 as u16 + blue.1 as u16).div_ceil(2) as u8);
    }

    #[test]
    fn a_side_by_side_frame_becomes_whole_yuyv_rows() {
        // Two rows of a frame one pixel wide per eye, and a stray byte.
        let rgb = [[255, 0, 0, 0, 0, 255], [0, 0, 255, 255, 0, 0]].concat();
        let mut partial = rgb.clone();
        partial.push(7);
        let yuyv = yuyv_from_rgb(&partial, 1);
        assert_eq!(yuyv.len(), 8);
        let mut first = [0u8; 4];
        rgb_row_to_yuyv(&rgb[..6], &mut first);
        assert_eq!(yuyv[..4], first);
        assert!(yuyv_from_rgb(&rgb, 0).is_empty(), "a width of 0 has no rows");
    }

    #[test]
    fn classes_follow_table_1() {
        let c = ColorClasses::default();
        assert_eq!(c.code(90, 200, 45), BLACK);
        assert_eq!(c.code(90, 30, 46), GRAY);
        assert_eq!(c.code(90, 30, 220), GRAY);
        assert_eq!(c.code(90, 30, 221), WHITE);
        assert_eq!(c.code(90, 31, 46), 90);
        assert!(is_chromatic(179) && !is_chromatic(GRAY));
    }

    #[test]
    fn hue_is_circular() {
        assert_eq!(hue_distance(2, 178), 4);
        assert_eq!(hue_distance(178, 2), 4);
        assert_eq!(hue_distance(0, 90), 90);
        assert_eq!(hue_distance(30, 40), 10);
        let m = circular_mean_hue([176, 178, 2, 4]).unwrap();
        assert!(m < 0.01 || (m - 180.0).abs() < 0.01, "{m}");
        assert!(circular_mean_hue([]).is_none());
    }
}
