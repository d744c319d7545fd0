//! Seeded Gaussian pixel noise, independent of how rows are spread over threads.

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

/// Seeded Gaussian noise for one row of one eye (independent of thread layout): standard
/// normal quantiles at 2^16 equally likely levels, picked by the row's random stream.
pub(super) struct Noise {
    rng: Option<StdRng>,
    sigma: f32,
    table: &'static [f32],
}

pub(super) const NOISE_LEVELS: usize = 1 << 16;

pub(super) fn normal_table() -> &'static [f32] {
    static TABLE: std::sync::OnceLock<Vec<f32>> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        (0..NOISE_LEVELS)
            .map(|k| normal_quantile((k as f64 + 0.5) / NOISE_LEVELS as f64) as f32)
            .collect()
    })
}

impl Noise {
    pub(super) fn new(seed: u64, eye: usize, row: usize, sigma: f32) -> Self {
        let rng = (sigma > 0.0).then(|| {
            let key = seed
                .wrapping_mul(0x9e37_79b9_7f4a_7c15)
                .wrapping_add(((eye as u64) << 32) | row as u64);
            StdRng::seed_from_u64(splitmix(key))
        });
        Self {
            rng,
            sigma,
            table: if sigma > 0.0 { normal_table() } else { &[] },
        }
    }

    #[inline]
    pub(super) fn next(&mut self) -> f32 {
        match self.rng.as_mut() {
            Some(rng) => self.table[(rng.random::<u32>() >> 16) as usize] * self.sigma,
            None => 0.0,
        }
    }
}

/// Inverse standard normal CDF (Acklam's rational approximation, relative error < 1.2e-9).
pub(super) fn normal_quantile(p: f64) -> f64 {
    pub(super) const A: [f64; 6] = [
        -3.969_683_028_665_376e1,
        2.209_460_984_245_205e2,
        -2.759_285_104_469_687e2,
        1.383_577_518_672_69e2,
        -3.066_479_806_614_716e1,
        2.506_628_277_459_239,
    ];
    pub(super) const B: [f64; 5] = [
        -5.447_609_879_822_406e1,
        1.615_858_368_580_409e2,
        -1.556_989_798_598_866e2,
        6.680_131_188_771_972e1,
        -1.328_068_155_288_572e1,
    ];
    pub(super) const C: [f64; 6] = [
        -7.784_894_002_430_293e-3,
        -3.223_964_580_411_365e-1,
        -2.400_758_277_161_838,
        -2.549_732_539_343_734,
        4.374_664_141_464_968,
        2.938_163_982_698_783,
    ];
    pub(super) const D: [f64; 4] = [
        7.784_695_709_041_462e-3,
        3.224_671_290_700_398e-1,
        2.445_134_137_142_996,
        3.754_408_661_907_416,
    ];
    pub(super) const P_LOW: f64 = 0.02425;
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    if p < P_LOW {
        tail((-2.0 * p.ln()).sqrt())
    } else if p > 1.0 - P_LOW {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    }
}

pub(super) fn splitmix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}
