//! The vectorised kernel against a scalar reference of the same counts.

use super::*;
use crate::vision::color::{hue_distance, is_chromatic};
use crate::vision::frame::{ColorPlane, PixelColor};
use crate::vision::lookup::{texel, Texel, OUTSIDE_TEXEL};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

const W: usize = 640;
const H: usize = 360;

/// A distorted camera for a 640×360 image.
fn camera() -> Intrinsics {
    let mut cam = Intrinsics::pinhole(350.0, 350.0, 319.5, 179.5);
    cam.k1 = -0.17;
    cam.k2 = 0.03;
    cam.p1 = 1e-3;
    cam
}

fn plane(px: impl Fn(usize, &mut StdRng) -> PixelColor, rng: &mut StdRng) -> ColorPlane {
    ColorPlane {
        width: W,
        height: H,
        px: (0..W * H).map(|i| px(i, rng)).collect(),
    }
}

/// Each pixel's texel encodes its column (mod 180) and row (mod 256).
fn coordinate_plane() -> ColorPlane {
    ColorPlane {
        width: W,
        height: H,
        px: (0..W * H)
            .map(|i| PixelColor {
                code: (i % W % 180) as u8,
                sat: (i / W % 256) as u8,
                hue: 0,
            })
            .collect(),
    }
}

/// Random model points (chromatic first, then achromatic) and outer points.
fn points(rng: &mut StdRng) -> PointSet {
    let (n, chromatic) = (700, 500);
    PointSet {
        inner_x: (0..n).map(|_| rng.random_range(-150.0..150.0)).collect(),
        inner_y: (0..n).map(|_| rng.random_range(-100.0..100.0)).collect(),
        inner_code: (0..n)
            .map(|i| {
                if i < chromatic {
                    rng.random_range(0..180)
                } else {
                    rng.random_range(252..=254)
                }
            })
            .collect(),
        inner_sat: (0..n).map(|_| rng.random()).collect(),
        inner_v: (0..n).map(|_| rng.random()).collect(),
        chromatic,
        outer_x: (0..300).map(|_| rng.random_range(-170.0..170.0)).collect(),
        outer_y: (0..300).map(|_| rng.random_range(-120.0..120.0)).collect(),
    }
}

/// A random placement in front of the camera, sometimes partly beside or behind it.
fn placement(rng: &mut StdRng) -> [Vector3<f64>; 3] {
    let angle: f64 = rng.random_range(-0.6..0.6);
    let scale = rng.random_range(0.3..3.0);
    let ax = Vector3::new(angle.cos(), angle.sin(), rng.random_range(-0.3..0.3)) * scale;
    let ay = Vector3::new(-angle.sin(), angle.cos(), rng.random_range(-0.3..0.3)) * scale;
    let t = Vector3::new(
        rng.random_range(-600.0..600.0),
        rng.random_range(-400.0..400.0),
        rng.random_range(-50.0..1500.0),
    );
    [ax, ay, t]
}

const TOL: Tolerances = Tolerances {
    hue: 15,
    sat: 50,
    stereo_hue: 5,
    stereo_sat: 25,
    outer: OuterTest {
        raw_hue: false,
        mean_hue: 10,
        threshold: 15,
        center_code: 12,
        center_sat: 150,
        sat_tolerance: 50,
    },
};

/// The outer test written plainly, from Table 1 and eq. 16.
fn reference_target(t: Texel, o: &OuterTest) -> bool {
    let (code, second) = ((t & 0xff) as u8, (t >> 8) as u8);
    let near = |h: u8| hue_distance(h, o.mean_hue) < o.threshold;
    if code == OUTSIDE {
        true
    } else if o.raw_hue {
        near(second)
    } else if is_chromatic(o.center_code) {
        is_chromatic(code) && near(code) && second.abs_diff(o.center_sat) <= o.sat_tolerance
    } else {
        code == o.center_code
    }
}

/// The texel under inner (`outer` false) or outer point `i`, one point at a time.
fn texel_at(pts: &PointSet, img: &LookupImage, p: &Projection, i: usize, outer: bool) -> Texel {
    let (x, y) = if outer {
        (pts.outer_x[i], pts.outer_y[i])
    } else {
        (pts.inner_x[i], pts.inner_y[i])
    };
    let (u, v) = pixel(p, x, y);
    let u = u.max(0.0).min((img.width - 1) as f32).round_ties_even() as usize;
    let v = v.max(0.0).min((img.height - 1) as f32).round_ties_even() as usize;
    img.px[v * img.width + u]
}

/// The plain scalar counts, one point at a time with branches.
fn reference(pts: &PointSet, images: [&LookupImage; 2], projections: [&Projection; 2], tol: &Tolerances) -> Counts {
    let mut c = Counts::default();
    for i in 0..pts.inner_x.len() {
        let [l, r] = [0, 1].map(|e| texel_at(pts, images[e], projections[e], i, false));
        let m = pts.inner_code[i];
        let matches = |t: Texel| {
            let (code, sat) = ((t & 0xff) as u8, (t >> 8) as u8);
            if is_chromatic(m) {
                is_chromatic(code) && hue_distance(m, code) <= tol.hue && pts.inner_sat[i].abs_diff(sat) <= tol.sat
            } else {
                code == m
            }
        };
        let (ml, mr) = (matches(l), matches(r));
        c.close[0] += ml as u32;
        c.close[1] += mr as u32;
        let (lc, rc) = ((l & 0xff) as u8, (r & 0xff) as u8);
        let same = if is_chromatic(m) {
            is_chromatic(rc)
                && hue_distance(lc, rc) <= tol.stereo_hue
                && ((l >> 8) as u8).abs_diff((r >> 8) as u8) <= tol.stereo_sat
        } else {
            mr
        };
        c.confirmed += (ml && same) as u32;
        for (seen, t) in c.inner_seen.iter_mut().zip([l, r]) {
            *seen += ((t & 0xff) as u8 != OUTSIDE) as u32;
        }
    }
    for e in 0..2 {
        c.outer_seen[e] = (0..pts.outer_x.len())
            .filter(|&i| (texel_at(pts, images[e], projections[e], i, true) & 0xff) as u8 != OUTSIDE)
            .count() as u32;
        c.background[e] = (0..pts.outer_x.len())
            .filter(|&i| !reference_target(texel_at(pts, images[e], projections[e], i, true), &tol.outer))
            .count() as u32;
    }
    c
}

fn random_colours(rng: &mut StdRng) -> LookupImage {
    let colours = plane(
        |_, rng| PixelColor {
            code: if rng.random::<f64>() < 0.8 {
                rng.random_range(0..180)
            } else {
                rng.random_range(252..=254)
            },
            sat: rng.random(),
            hue: 0,
        },
        rng,
    );
    lookup(&colours)
}

/// The lookup image of a whole plane (second byte: the saturation).
fn lookup(plane: &ColorPlane) -> LookupImage {
    let (w, h) = (plane.width + 2, plane.height + 2);
    let mut px = vec![OUTSIDE_TEXEL; w * h];
    for (row, src) in px.chunks_exact_mut(w).skip(1).zip(plane.px.chunks_exact(plane.width)) {
        for (t, c) in row[1..].iter_mut().zip(src) {
            *t = texel(c.code, c.sat);
        }
    }
    LookupImage {
        width: w,
        height: h,
        origin: (0, 0),
        px,
    }
}

#[test]
fn fast_path_counts_exactly_like_the_scalar_reference() {
    let mut rng = StdRng::seed_from_u64(5);
    let (left, right) = (random_colours(&mut rng), random_colours(&mut rng));
    let (cam, pts) = (camera(), points(&mut rng));
    let (mut seen, mut confirmed, mut cut, mut wholly) = (0, 0, 0, 0);
    let extent = |a: &[f32], b: &[f32]| a.iter().chain(b).fold(0.0f32, |m, v| m.max(v.abs()));
    let reach = [extent(&pts.inner_x, &pts.outer_x), extent(&pts.inner_y, &pts.outer_y)];
    // The three outer tests: chromatic centre, achromatic centre, the paper's raw hue.
    let outers = [
        TOL.outer,
        OuterTest {
            center_code: crate::vision::color::GRAY,
            ..TOL.outer
        },
        OuterTest {
            raw_hue: true,
            ..TOL.outer
        },
    ];
    for i in 0..300 {
        let tol = Tolerances {
            outer: outers[i % 3],
            ..TOL
        };
        let [ax, ay, t] = placement(&mut rng);
        // The right camera sees the placement shifted by a baseline.
        let pl = projection(&cam, (0, 0), [&ax, &ay, &t]);
        let pr = projection(&cam, (0, 0), [&ax, &ay, &(t + Vector3::new(-120.0, 0.0, 0.0))]);
        let fast = count(&pts, [&left, &right], [&pl, &pr], &tol, true);
        assert_eq!(fast, reference(&pts, [&left, &right], [&pl, &pr], &tol));
        assert_eq!(
            count_chunks::<true, true>(&pts, [&left, &right], [&pl, &pr], &tol),
            fast
        );
        let unseen = count(&pts, [&left, &right], [&pl, &pr], &tol, false);
        assert_eq!(
            unseen,
            Counts {
                inner_seen: [0; 2],
                outer_seen: [0; 2],
                ..fast
            }
        );
        let only_left = count_left(&pts, &left, &pl, &tol, true);
        assert_eq!(
            only_left,
            Counts {
                close: [fast.close[0], 0],
                background: [fast.background[0], 0],
                confirmed: 0,
                inner_seen: [fast.inner_seen[0], 0],
                outer_seen: [fast.outer_seen[0], 0],
            }
        );
        seen += (fast.close[0] > 0) as u32;
        confirmed += fast.confirmed;
        cut += (fast.inner_seen[0] > 0 && (fast.inner_seen[0] as usize) < pts.inner_x.len()) as u32;
        // A model whose reach lands wholly on the image has every point on it.
        if wholly_on(&left, &pl, reach, 1.0) {
            let n = [pts.inner_x.len(), pts.outer_x.len()].map(|n| n as u32);
            assert_eq!([fast.inner_seen[0], fast.outer_seen[0]], n);
            wholly += 1;
        }
    }
    assert!(wholly > 20, "some placements lie wholly on the image: {wholly}");
    assert!(seen > 100, "most placements see part of the image: {seen}");
    assert!(cut > 20, "some placements are cut by the image's border: {cut}");
    assert!(confirmed > 50, "some random matches are confirmed: {confirmed}");
    // Identical views confirm exactly the left-image matches.
    let p = projection(
        &cam,
        (0, 0),
        [&Vector3::x(), &Vector3::y(), &Vector3::new(0.0, 0.0, 300.0)],
    );
    let same = count(&pts, [&left, &left], [&p, &p], &TOL, false);
    assert_eq!(same.confirmed, same.close[0]);
    assert!(same.confirmed > 0);
}

#[test]
fn points_land_on_the_pixel_the_camera_model_projects_to() {
    let mut rng = StdRng::seed_from_u64(6);
    let coords = coordinate_plane();
    let img = lookup(&coords);
    let cam = camera();
    let mut chunk = Chunk::new();
    let (mut exact, mut total) = (0, 0);
    for _ in 0..200 {
        let [ax, ay, t] = placement(&mut rng);
        let p = projection(&cam, (0, 0), [&ax, &ay, &t]);
        let (xs, ys): (Vec<f32>, Vec<f32>) = (0..CHUNK)
            .map(|_| (rng.random_range(-150.0..150.0), rng.random_range(-100.0..100.0)))
            .unzip();
        let tex = chunk.read(&img, &p, &xs, &ys);
        for ((&x, &y), &got) in xs.iter().zip(&ys).zip(tex) {
            let got = got as Texel;
            let q = t + ax * x as f64 + ay * y as f64;
            let want = match cam.project(&nalgebra::Point3::from(q)) {
                Some(q) if q.x > -0.5 && q.y > -0.5 && q.x < W as f64 - 0.5 && q.y < H as f64 - 0.5 => {
                    let (u, v) = (q.x.round() as usize, q.y.round() as usize);
                    Some(((u % 180) as Texel) | ((v % 256) as Texel) << 8)
                }
                _ => None,
            };
            match want {
                Some(w) => {
                    exact += (got == w) as u32;
                    total += 1;
                }
                None => assert!(
                    got == crate::vision::lookup::OUTSIDE_TEXEL || q.z > 0.0,
                    "behind or off the image"
                ),
            }
        }
    }
    assert!(total > 10_000, "{total} points on the image");
    assert!(
        exact as f64 >= 0.999 * total as f64,
        "{exact} of {total} on the same pixel"
    );
}

#[test]
fn a_region_reads_like_the_whole_image_inside_it_and_outside_beyond() {
    let mut rng = StdRng::seed_from_u64(7);
    let coords = coordinate_plane();
    let full = lookup(&coords);
    let (cols, rows) = (200..500, 100..250);
    let mut region = LookupImage {
        width: cols.len() + 2,
        height: rows.len() + 2,
        origin: (cols.start, rows.start),
        px: vec![OUTSIDE_TEXEL; (cols.len() + 2) * (rows.len() + 2)],
    };
    for v in rows.clone() {
        for u in cols.clone() {
            region.px[(v - rows.start + 1) * region.width + u - cols.start + 1] = full.px[(v + 1) * full.width + u + 1];
        }
    }
    let cam = camera();
    let (mut a, mut b) = (Chunk::new(), Chunk::new());
    let (mut agree, mut inside, mut total) = (0, 0, 0);
    for _ in 0..200 {
        let [ax, ay, t] = placement(&mut rng);
        let whole_p = projection(&cam, (0, 0), [&ax, &ay, &t]);
        let part_p = projection(&cam, region.origin, [&ax, &ay, &t]);
        let (xs, ys): (Vec<f32>, Vec<f32>) = (0..CHUNK)
            .map(|_| (rng.random_range(-150.0..150.0), rng.random_range(-100.0..100.0)))
            .unzip();
        let whole = a.read(&full, &whole_p, &xs, &ys).to_vec();
        let part = b.read(&region, &part_p, &xs, &ys);
        for (k, (&w, &p)) in whole.iter().zip(part).enumerate() {
            let i = a.index(k) as usize;
            let (u, v) = ((i % full.width).wrapping_sub(1), (i / full.width).wrapping_sub(1));
            let want = if cols.contains(&u) && rows.contains(&v) {
                inside += 1;
                w
            } else {
                OUTSIDE_TEXEL as u32
            };
            agree += (p == want) as u32;
            total += 1;
        }
    }
    assert!(inside > 5_000, "{inside} points in the region");
    assert!(agree as f64 >= 0.999 * total as f64, "{agree} of {total} agree");
}
