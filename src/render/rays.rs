//! Per-camera tables of viewing rays through the pixel corners.
//!
//! Inverting the lens distortion ([`Intrinsics::ray`]) is by far the most expensive part of
//! inverse mapping, and it depends only on the camera, so the rays through all pixel corners
//! `(i − ½, j − ½)` are computed once and cached for the last few cameras. Rays inside a
//! pixel (its centre, supersamples) are bilinear blends of its four corner rays; the
//! distortion is so smooth at pixel scale that this differs from the exact ray by < 1e-3 px.

use std::sync::{Arc, Mutex};

use crate::camera::Intrinsics;

/// How many tables are kept (two eyes of two rigs).
const CACHE_SIZE: usize = 4;

/// Normalised ray coordinates `(x, y)` (ray `(x, y, 1)`) at the `(w+1) × (h+1)` pixel corners.
#[derive(Debug)]
pub(crate) struct RayTable {
    key: [u64; 11],
    stride: usize,
    xy: Vec<[f32; 2]>,
}

impl RayTable {
    /// Ray coordinates at corner `(i − ½, j − ½)`, `i ∈ 0..=w`, `j ∈ 0..=h`.
    #[inline]
    pub(crate) fn corner(&self, i: usize, j: usize) -> [f64; 2] {
        let c = self.xy[j * self.stride + i];
        [c[0] as f64, c[1] as f64]
    }
}

static CACHE: Mutex<Vec<Arc<RayTable>>> = Mutex::new(Vec::new());

fn key(cam: &Intrinsics, w: usize, h: usize) -> [u64; 11] {
    [
        cam.fx.to_bits(),
        cam.fy.to_bits(),
        cam.cx.to_bits(),
        cam.cy.to_bits(),
        cam.k1.to_bits(),
        cam.k2.to_bits(),
        cam.p1.to_bits(),
        cam.p2.to_bits(),
        cam.k3.to_bits(),
        w as u64,
        h as u64,
    ]
}

/// The (cached) corner-ray table of a `w × h` image of `cam`.
pub(crate) fn table(cam: &Intrinsics, w: usize, h: usize) -> Arc<RayTable> {
    let k = key(cam, w, h);
    {
        let mut cache = CACHE.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(pos) = cache.iter().position(|t| t.key == k) {
            let t = cache.remove(pos);
            cache.push(t.clone());
            return t;
        }
    }
    let t = Arc::new(build(cam, w, h, k));
    let mut cache = CACHE.lock().unwrap_or_else(|e| e.into_inner());
    if cache.len() >= CACHE_SIZE {
        cache.remove(0);
    }
    cache.push(t.clone());
    t
}

fn build(cam: &Intrinsics, w: usize, h: usize, key: [u64; 11]) -> RayTable {
    let stride = w + 1;
    let mut xy = vec![[0.0f32; 2]; stride * (h + 1)];
    let threads = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
        .clamp(1, 64);
    let band_rows = (h + 1).div_ceil(threads).max(1);
    std::thread::scope(|s| {
        for (band, chunk) in xy.chunks_mut(stride * band_rows).enumerate() {
            s.spawn(move || {
                for (k, c) in chunk.iter_mut().enumerate() {
                    let j = band * band_rows + k / stride;
                    let i = k % stride;
                    let r = cam.ray(i as f64 - 0.5, j as f64 - 0.5);
                    *c = [r.x as f32, r.y as f32];
                }
            });
        }
    });
    RayTable { key, stride, xy }
}
