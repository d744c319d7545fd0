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
/// use photopose::color::{hue_distance, rgb_to_hsv};
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
