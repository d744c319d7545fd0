//! Mip-mapped RGB textures with bilinear/trilinear sampling.
//!
//! Texture coordinates are continuous texel units of level 0: texel `k` spans `[k, k+1)`,
//! so the texture's outer edges are at `0` and `width`. The footprint (texels per output
//! pixel or sub-sample) selects the mip level, which keeps minified photos free of aliasing.

use image::RgbImage;

/// What happens outside `[0, width) × [0, height)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Wrap {
    /// Repeat the border texel.
    Clamp,
    /// Mirror-repeat the texture (endless walls without seams).
    Mirror,
}

#[derive(Debug, Clone)]
struct Level {
    w: usize,
    h: usize,
    /// Level texels per level-0 texel, along x and y.
    sx: f64,
    sy: f64,
    data: Vec<u8>,
}

/// A texture with its box-filtered mip pyramid.
#[derive(Debug, Clone)]
pub(crate) struct MipTexture {
    levels: Vec<Level>,
}

impl MipTexture {
    /// Builds the pyramid; an empty image becomes a 1×1 mid-grey texture.
    pub(crate) fn new(img: &RgbImage) -> Self {
        let base = if img.width() == 0 || img.height() == 0 {
            Level {
                w: 1,
                h: 1,
                sx: 1.0,
                sy: 1.0,
                data: vec![128, 128, 128],
            }
        } else {
            Level {
                w: img.width() as usize,
                h: img.height() as usize,
                sx: 1.0,
                sy: 1.0,
                data: img.as_raw().clone(),
            }
        };
        let mut levels = vec![base];
        while levels.len() < 16 {
            let prev = &levels[levels.len() - 1];
            if prev.w == 1 && prev.h == 1 {
                break;
            }
            let mut next = downsample(prev);
            next.sx = next.w as f64 / levels[0].w as f64;
            next.sy = next.h as f64 / levels[0].h as f64;
            levels.push(next);
        }
        Self { levels }
    }

    /// Level-0 width in texels.
    pub(crate) fn width(&self) -> f64 {
        self.levels[0].w as f64
    }

    /// Level-0 height in texels.
    pub(crate) fn height(&self) -> f64 {
        self.levels[0].h as f64
    }

    /// Samples at level-0 texel coordinates `(u, v)` for a footprint of `footprint`
    /// level-0 texels (trilinear between the two nearest levels). Returns RGB in 0..=255.
    #[inline]
    pub(crate) fn sample(&self, u: f64, v: f64, footprint: f64, wrap: Wrap) -> [f32; 3] {
        let lod = if footprint.is_finite() && footprint > 1.0 {
            fast_log2(footprint)
        } else {
            0.0
        };
        let max = (self.levels.len() - 1) as f64;
        let lod = lod.min(max);
        let l0 = lod.floor() as usize;
        let t = (lod - l0 as f64) as f32;
        let a = self.bilinear(l0, u, v, wrap);
        if t <= 1e-3 || l0 + 1 >= self.levels.len() {
            return a;
        }
        let b = self.bilinear(l0 + 1, u, v, wrap);
        [
            a[0] + (b[0] - a[0]) * t,
            a[1] + (b[1] - a[1]) * t,
            a[2] + (b[2] - a[2]) * t,
        ]
    }

    #[inline]
    fn bilinear(&self, level: usize, u: f64, v: f64, wrap: Wrap) -> [f32; 3] {
        let lv = &self.levels[level];
        // Level coordinates, then shift so that integers are texel centres.
        let x = u * lv.sx - 0.5;
        let y = v * lv.sy - 0.5;
        if !x.is_finite() || !y.is_finite() {
            return [0.0; 3];
        }
        let x = x.clamp(-1e9, 1e9);
        let y = y.clamp(-1e9, 1e9);
        let (x0, y0) = (floor_i64(x), floor_i64(y));
        let fx = (x - x0 as f64) as f32;
        let fy = (y - y0 as f64) as f32;
        let xa = wrap_index(x0, lv.w, wrap) * 3;
        let xb = wrap_index(x0 + 1, lv.w, wrap) * 3;
        let ra = wrap_index(y0, lv.h, wrap) * lv.w * 3;
        let rb = wrap_index(y0 + 1, lv.h, wrap) * lv.w * 3;
        let d = lv.data.as_slice();
        let (Some(p00), Some(p10), Some(p01), Some(p11)) = (
            d.get(ra + xa..ra + xa + 3),
            d.get(ra + xb..ra + xb + 3),
            d.get(rb + xa..rb + xa + 3),
            d.get(rb + xb..rb + xb + 3),
        ) else {
            return [0.0; 3];
        };
        let w11 = fx * fy;
        let w10 = fx - w11;
        let w01 = fy - w11;
        let w00 = 1.0 - fx - w01;
        let mut out = [0.0f32; 3];
        for c in 0..3 {
            out[c] = w00 * p00[c] as f32 + w10 * p10[c] as f32 + w01 * p01[c] as f32 + w11 * p11[c] as f32;
        }
        out
    }
}

/// `floor` without a libm call (`|x| <= 1e9`).
#[inline]
fn floor_i64(x: f64) -> i64 {
    let t = x as i64;
    if (t as f64) > x {
        t - 1
    } else {
        t
    }
}

/// Piecewise-linear `log2` (exact at powers of two, error < 0.09): mip selection only.
#[inline]
fn fast_log2(x: f64) -> f64 {
    let bits = x.to_bits();
    let exp = ((bits >> 52) & 0x7ff) as i64 - 1023;
    let mantissa = f64::from_bits((bits & 0x000f_ffff_ffff_ffff) | 0x3ff0_0000_0000_0000);
    exp as f64 + (mantissa - 1.0)
}

#[inline]
fn wrap_index(i: i64, n: usize, wrap: Wrap) -> usize {
    let n = n as i64;
    if (0..n).contains(&i) {
        return i as usize;
    }
    match wrap {
        Wrap::Clamp => i.clamp(0, n - 1) as usize,
        Wrap::Mirror => {
            let m = i.rem_euclid(2 * n);
            (if m >= n { 2 * n - 1 - m } else { m }) as usize
        }
    }
}

/// 2×2 box filter (the last row/column is repeated for odd sizes).
fn downsample(src: &Level) -> Level {
    let w = src.w.div_ceil(2);
    let h = src.h.div_ceil(2);
    let mut data = vec![0u8; w * h * 3];
    for y in 0..h {
        let y0 = (2 * y).min(src.h - 1);
        let y1 = (2 * y + 1).min(src.h - 1);
        for x in 0..w {
            let x0 = (2 * x).min(src.w - 1);
            let x1 = (2 * x + 1).min(src.w - 1);
            for c in 0..3 {
                let s = src.data[(y0 * src.w + x0) * 3 + c] as u32
                    + src.data[(y0 * src.w + x1) * 3 + c] as u32
                    + src.data[(y1 * src.w + x0) * 3 + c] as u32
                    + src.data[(y1 * src.w + x1) * 3 + c] as u32;
                data[(y * w + x) * 3 + c] = ((s + 2) / 4) as u8;
            }
        }
    }
    Level {
        w,
        h,
        sx: 1.0,
        sy: 1.0,
        data,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::Rgb;

    #[test]
    fn bilinear_hits_texel_centres_and_mirrors() {
        let mut img = RgbImage::new(2, 1);
        img.put_pixel(0, 0, Rgb([0, 0, 0]));
        img.put_pixel(1, 0, Rgb([200, 100, 50]));
        let t = MipTexture::new(&img);
        assert_eq!(t.sample(0.5, 0.5, 1.0, Wrap::Clamp), [0.0, 0.0, 0.0]);
        assert_eq!(t.sample(1.5, 0.5, 1.0, Wrap::Clamp), [200.0, 100.0, 50.0]);
        assert_eq!(t.sample(1.0, 0.5, 1.0, Wrap::Clamp), [100.0, 50.0, 25.0]);
        // Mirror: texel 2 is texel 1 again, texel 3 is texel 0.
        assert_eq!(t.sample(2.5, 0.5, 1.0, Wrap::Mirror), [200.0, 100.0, 50.0]);
        assert_eq!(t.sample(3.5, 0.5, 1.0, Wrap::Mirror), [0.0, 0.0, 0.0]);
        assert_eq!(t.sample(-0.5, 0.5, 1.0, Wrap::Mirror), [0.0, 0.0, 0.0]);
    }

    #[test]
    fn large_footprint_averages() {
        let img = RgbImage::from_fn(8, 8, |x, y| {
            if (x + y) % 2 == 0 {
                Rgb([255, 255, 255])
            } else {
                Rgb([0, 0, 0])
            }
        });
        let t = MipTexture::new(&img);
        let c = t.sample(4.0, 4.0, 8.0, Wrap::Clamp);
        assert!((c[0] - 127.5).abs() < 2.0, "{c:?}");
        let empty = MipTexture::new(&RgbImage::new(0, 0));
        assert_eq!(empty.sample(3.0, 3.0, 1.0, Wrap::Clamp), [128.0; 3]);
    }
}
