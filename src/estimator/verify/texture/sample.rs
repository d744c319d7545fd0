//! Bilinear samples of an eye's brightness and detail at a batch of image points: the
//! texture terms' inner loop. On x86-64 with AVX2 eight points are sampled at a time
//! (gathered loads), with the same arithmetic, in the same order, as the portable loop:
//! the two give the same bits.

use super::{Brightness, Sample, BATCH};

/// One eye's samples at a batch of points (see [`Brightness::sample_batch`]).
pub(super) struct Samples {
    value: [f32; BATCH],
    detail: [f32; BATCH],
    noise: [f32; BATCH],
    /// Bit `i % 8` of byte `i / 8`: whether point `i`'s four pixels are in the eye.
    seen: [u8; BATCH / 8],
}

impl Samples {
    pub fn new() -> Self {
        Self {
            value: [0.0; BATCH],
            detail: [0.0; BATCH],
            noise: [0.0; BATCH],
            seen: [0; BATCH / 8],
        }
    }

    /// Sample `i`: brightness, detail and the detail's noise variance.
    #[inline]
    pub fn at(&self, i: usize) -> Sample {
        (self.value[i], self.detail[i], self.noise[i])
    }

    /// Whether point `i` was seen (its four pixels are in the eye).
    #[inline]
    pub fn seen(&self, i: usize) -> bool {
        self.seen[i / 8] >> (i % 8) & 1 == 1
    }

    /// Sample `i`'s brightness.
    #[inline]
    pub fn value(&self, i: usize) -> f32 {
        self.value[i]
    }
}

impl Brightness {
    /// Bilinear samples of the brightness and the detail at the pixels `(us[i], vs[i])`
    /// of a batch, and the variance of the noise in each detail sample; not
    /// [`Samples::seen`] outside the eye. The whole batch is sampled: entries past the
    /// caller's points are not used.
    pub(super) fn sample_batch(&self, us: &[f32; BATCH], vs: &[f32; BATCH], out: &mut Samples) {
        if self.width < 2 || self.height < 2 {
            out.seen.fill(0);
            return;
        }
        #[cfg(target_arch = "x86_64")]
        if self.px.len() < avx2::MAX_PIXELS && std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2, and the eye has at least 2 × 2 pixels and
            // fewer than `avx2::MAX_PIXELS`.
            return unsafe { avx2::sample_batch(self, us, vs, out) };
        }
        portable(self, us, vs, out);
    }

    /// The bilinear brightness at pixel `(u, v)`; `None` where its four pixels are not
    /// all in the eye.
    pub fn brightness_at(&self, u: f32, v: f32) -> Option<f32> {
        let (u, v) = (u - self.origin.0, v - self.origin.1);
        let (x0, y0) = (u as i64, v as i64);
        let (w, h) = (self.width as i64, self.height as i64);
        if u < 0.0 || v < 0.0 || x0 >= w - 1 || y0 >= h - 1 {
            return None;
        }
        let k = (y0 * w + x0) as usize;
        let p = &self.px;
        let (a, b, c, d) = (p[k], p[k + 1], p[k + self.width], p[k + self.width + 1]);
        Some(lerp2(a[0], b[0], c[0], d[0], u - x0 as f32, v - y0 as f32))
    }
}

/// [`Brightness::sample_batch`] one point at a time, on an eye of at least 2 × 2 pixels:
/// every pixel read is in the eye, seen or not (an unseen sample reads the first).
fn portable(eye: &Brightness, us: &[f32; BATCH], vs: &[f32; BATCH], out: &mut Samples) {
    let (w, h) = (eye.width as i64, eye.height as i64);
    let p = &eye.px[..eye.width * eye.height];
    out.seen.fill(0);
    for i in 0..BATCH {
        let (u, v) = (us[i] - eye.origin.0, vs[i] - eye.origin.1);
        let (x0, y0) = (u as i64, v as i64);
        let inside = u >= 0.0 && v >= 0.0 && x0 < w - 1 && y0 < h - 1;
        let k = if inside { (y0 * w + x0) as usize } else { 0 };
        let (fx, fy) = (u - x0 as f32, v - y0 as f32);
        let (a, b, c, d) = (p[k], p[k + 1], p[k + eye.width], p[k + eye.width + 1]);
        let at = |j: usize| lerp2(a[j], b[j], c[j], d[j], fx, fy);
        let noise = eye.noise_var * noise_weight(fx, fy);
        (out.value[i], out.detail[i], out.noise[i]) = (at(0), at(1), noise);
        out.seen[i / 8] |= u8::from(inside) << (i % 8);
    }
}

/// Bilinear interpolation between `a` (top left), `b` (top right), `c` (bottom left)
/// and `d` at fractions `fx` right and `fy` down.
#[inline(always)]
fn lerp2(a: f32, b: f32, c: f32, d: f32, fx: f32, fy: f32) -> f32 {
    let top = a + fx * (b - a);
    let bottom = c + fx * (d - c);
    top + fy * (bottom - top)
}

/// The share of a pixel's noise variance left in a bilinear sample at fractions
/// `fx`, `fy`: the sum of the squared weights.
#[inline(always)]
fn noise_weight(fx: f32, fy: f32) -> f32 {
    ((1.0 - fx).powi(2) + fx * fx) * ((1.0 - fy).powi(2) + fy * fy)
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use std::arch::x86_64::*;

    use super::{Brightness, Samples, BATCH};

    /// Lanes per vector.
    const LANES: usize = 8;

    /// Pixels an eye sampled here has fewer of: their indices are 32-bit lanes.
    pub(super) const MAX_PIXELS: usize = 1 << 30;

    /// [`super::portable`] eight points at a time.
    ///
    /// # Safety
    /// The CPU supports AVX2, and the eye has at least 2 × 2 pixels and fewer than
    /// [`MAX_PIXELS`].
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn sample_batch(eye: &Brightness, us: &[f32; BATCH], vs: &[f32; BATCH], out: &mut Samples) {
        let (w, h) = (eye.width as i32, eye.height as i32);
        let p = &eye.px[..eye.width * eye.height];
        let origin = (_mm256_set1_ps(eye.origin.0), _mm256_set1_ps(eye.origin.1));
        let last = (_mm256_set1_epi32(w - 1), _mm256_set1_epi32(h - 1));
        let (row, one) = (_mm256_set1_epi32(w), _mm256_set1_ps(1.0));
        for i in (0..BATCH).step_by(LANES) {
            // `i + LANES <= BATCH`: the loads and stores stay within the batch's arrays.
            let u = _mm256_sub_ps(_mm256_loadu_ps(us[i..].as_ptr()), origin.0);
            let v = _mm256_sub_ps(_mm256_loadu_ps(vs[i..].as_ptr()), origin.1);
            // Truncated like `as`; out of range gives i32::MIN, which is not inside.
            let (x0, y0) = (_mm256_cvttps_epi32(u), _mm256_cvttps_epi32(v));
            let ahead = _mm256_and_ps(
                _mm256_cmp_ps::<_CMP_GE_OQ>(u, _mm256_setzero_ps()),
                _mm256_cmp_ps::<_CMP_GE_OQ>(v, _mm256_setzero_ps()),
            );
            let inside = _mm256_and_si256(
                _mm256_castps_si256(ahead),
                _mm256_and_si256(within(x0, last.0), within(y0, last.1)),
            );
            // Index of the top-left pixel, 0 outside.
            let k = _mm256_and_si256(inside, _mm256_add_epi32(_mm256_mullo_epi32(y0, row), x0));
            let [va, da] = pixels(p, k, 0);
            let [vb, db] = pixels(p, k, 1);
            let [vc, dc] = pixels(p, k, w);
            let [vd, dd] = pixels(p, k, w + 1);
            let fx = _mm256_sub_ps(u, _mm256_cvtepi32_ps(x0));
            let fy = _mm256_sub_ps(v, _mm256_cvtepi32_ps(y0));
            let square = |a: __m256| _mm256_mul_ps(a, a);
            let (gx, gy) = (_mm256_sub_ps(one, fx), _mm256_sub_ps(one, fy));
            let weight = _mm256_mul_ps(
                _mm256_add_ps(square(gx), square(fx)),
                _mm256_add_ps(square(gy), square(fy)),
            );
            let noise = _mm256_mul_ps(_mm256_set1_ps(eye.noise_var), weight);
            // SAFETY: see the loop's first line.
            unsafe {
                _mm256_storeu_ps(out.value[i..].as_mut_ptr(), lerp2(va, vb, vc, vd, fx, fy));
                _mm256_storeu_ps(out.detail[i..].as_mut_ptr(), lerp2(da, db, dc, dd, fx, fy));
                _mm256_storeu_ps(out.noise[i..].as_mut_ptr(), noise);
            }
            out.seen[i / LANES] = _mm256_movemask_ps(_mm256_castsi256_ps(inside)) as u8;
        }
    }

    /// The lanes where `0 <= x < last`.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn within(x: __m256i, last: __m256i) -> __m256i {
        _mm256_and_si256(
            _mm256_cmpgt_epi32(x, _mm256_set1_epi32(-1)),
            _mm256_cmpgt_epi32(last, x),
        )
    }

    /// The brightness and the detail of pixel `k + offset` in each lane: a 64-bit
    /// gather of both per four lanes, then split into two vectors.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn pixels(p: &[[f32; 2]], k: __m256i, offset: i32) -> [__m256; 2] {
        let at = _mm256_add_epi32(k, _mm256_set1_epi32(offset));
        // SAFETY: every pixel read is within `p` (`w * h` pixels): inside, the
        // largest is `(y0 + 1) * w + x0 + 1` with `y0 + 1 < h` and `x0 + 1 < w`;
        // elsewhere `k` is 0 and the largest `w + 1 < 2 * w <= w * h`, as the eye has
        // at least 2 × 2 pixels.
        let gather = |lanes: __m128i| unsafe { _mm256_castpd_ps(_mm256_i32gather_pd::<8>(p.as_ptr().cast(), lanes)) };
        let (lo, hi) = (
            gather(_mm256_castsi256_si128(at)),
            gather(_mm256_extracti128_si256::<1>(at)),
        );
        // [v0 v1 v4 v5 | v2 v3 v6 v7] and the details alike, then in lane order.
        let order = |a: __m256| _mm256_castpd_ps(_mm256_permute4x64_pd::<0xD8>(_mm256_castps_pd(a)));
        [
            order(_mm256_shuffle_ps::<0x88>(lo, hi)),
            order(_mm256_shuffle_ps::<0xDD>(lo, hi)),
        ]
    }

    /// [`super::lerp2`] in each lane.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn lerp2(a: __m256, b: __m256, c: __m256, d: __m256, fx: __m256, fy: __m256) -> __m256 {
        let top = _mm256_add_ps(a, _mm256_mul_ps(fx, _mm256_sub_ps(b, a)));
        let bottom = _mm256_add_ps(c, _mm256_mul_ps(fx, _mm256_sub_ps(d, c)));
        _mm256_add_ps(top, _mm256_mul_ps(fy, _mm256_sub_ps(bottom, top)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `w × h` brightness of pseudo-random values and details at `origin`.
    fn brightness(w: usize, h: usize, origin: (f32, f32)) -> Brightness {
        let px = (0..w * h)
            .map(|i| {
                let k = (i as u32).wrapping_mul(2_654_435_761);
                [(k >> 24) as f32 + 0.25, (k >> 16 & 0xff) as f32 / 7.0 - 18.0]
            })
            .collect();
        Brightness {
            origin,
            width: w,
            height: h,
            px,
            noise_var: 3.5,
        }
    }

    #[test]
    fn a_batch_samples_the_same_bits_as_the_portable_loop_at_edges_and_beyond() {
        let eye = brightness(37, 23, (100.0, 50.0));
        let (mut us, mut vs) = ([0.0f32; BATCH], [0.0f32; BATCH]);
        // Inside, on the last pixels, just outside, far outside, behind the camera
        // (-1), not a number and too large to truncate.
        let special = [-1.0, 99.99, 100.0, 135.0, 135.5, 136.0, 137.0, f32::NAN, 3.0e9, -3.0e9];
        for i in 0..BATCH {
            let t = i as f32 * 0.618;
            us[i] = 99.0 + (t * 41.3) % 40.0;
            vs[i] = 49.0 + (t * 17.9) % 26.0;
        }
        for (i, &s) in special.iter().enumerate() {
            us[i] = s;
            vs[100 + i] = s - 50.0;
        }
        let (mut fast, mut slow) = (Samples::new(), Samples::new());
        eye.sample_batch(&us, &vs, &mut fast);
        portable(&eye, &us, &vs, &mut slow);
        assert_eq!(fast.seen, slow.seen);
        let seen = (0..BATCH).filter(|&i| slow.seen(i)).count();
        assert!(seen > BATCH / 2 && seen < BATCH, "{seen} of {BATCH} seen");
        for i in (0..BATCH).filter(|&i| slow.seen(i)) {
            let bits = |s: Sample| [s.0.to_bits(), s.1.to_bits(), s.2.to_bits()];
            assert_eq!(
                bits(fast.at(i)),
                bits(slow.at(i)),
                "point {i} at ({}, {})",
                us[i],
                vs[i]
            );
        }
    }

    #[test]
    fn a_sample_interpolates_the_four_pixels_around_it() {
        let eye = brightness(4, 3, (10.0, 20.0));
        let (mut us, mut vs) = ([0.0f32; BATCH], [0.0f32; BATCH]);
        (us[0], vs[0]) = (11.25, 21.5);
        let mut s = Samples::new();
        eye.sample_batch(&us, &vs, &mut s);
        let px = |x: usize, y: usize, j: usize| eye.px[y * 4 + x][j];
        let want = |j| {
            let top = px(1, 1, j) * 0.75 + px(2, 1, j) * 0.25;
            let bottom = px(1, 2, j) * 0.75 + px(2, 2, j) * 0.25;
            (top + bottom) / 2.0
        };
        assert!(s.seen(0) && !s.seen(1), "(0, 0) is outside the eye at (10, 20)");
        let (value, detail, noise) = s.at(0);
        assert!((value - want(0)).abs() < 1e-3 && (detail - want(1)).abs() < 1e-3);
        // Weights 0.75/0.25 across and 0.5/0.5 down: (0.5625 + 0.0625) × 0.5.
        assert!((noise - 3.5 * 0.3125).abs() < 1e-6, "{noise}");
    }
}
