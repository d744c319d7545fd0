//! Geometry and effect tests of the renderer against the forward projection.

use super::*;
use image::Rgb;
use nalgebra::{Point2, UnitQuaternion, Vector3};

const RED: [u8; 3] = [255, 0, 0];
const BLUE: [u8; 3] = [0, 0, 255];

fn lens(distorted: bool, cx: f64) -> Intrinsics {
    if distorted {
        Intrinsics {
            fx: 500.0,
            fy: 501.0,
            cx,
            cy: 181.0,
            k1: -0.17,
            k2: 0.025,
            p1: 0.0004,
            p2: -0.0003,
            k3: -0.001,
        }
    } else {
        Intrinsics::pinhole(500.0, 500.0, cx, 180.0)
    }
}

fn rig(distorted: bool) -> StereoRig {
    StereoRig {
        width: 640,
        height: 360,
        left: lens(distorted, 320.0),
        right: lens(distorted, 316.0),
        right_from_left: Isometry3::from_parts(
            Translation3::new(-120.0, 0.5, 1.0),
            UnitQuaternion::from_euler_angles(0.002, -0.01, 0.001),
        ),
    }
}

/// A hand frame that differs from the left camera (exercises the pose composition).
fn left_from_hand() -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(10.0, -5.0, 20.0),
        UnitQuaternion::from_euler_angles(0.05, -0.03, 0.1),
    )
}

fn scene_with(left_from_model: Isometry3<f64>, colour: [u8; 3], size: [f64; 2]) -> Scene {
    Scene {
        card: Card {
            texture: RgbImage::from_pixel(40, 30, Rgb(colour)),
            hand_from_model: left_from_hand().inverse() * left_from_model,
            size_mm: size,
        },
        background: Background::solid(BLUE, 1500.0),
        noise_sigma: 0.0,
        brightness: 1.0,
        occluder: None,
        seed: 0,
    }
}

fn pose(t: [f64; 3], euler: [f64; 3]) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(t[0], t[1], t[2]),
        UnitQuaternion::from_euler_angles(euler[0], euler[1], euler[2]),
    )
}

fn pixel(img: &RgbImage, rig: &StereoRig, eye: usize, u: i64, v: i64) -> [u8; 3] {
    let x = u.clamp(0, rig.width as i64 - 1) as u32 + eye as u32 * rig.width;
    let y = v.clamp(0, rig.height as i64 - 1) as u32;
    img.get_pixel(x, y).0
}

fn at(img: &RgbImage, rig: &StereoRig, eye: usize, p: Point2<f64>) -> [u8; 3] {
    pixel(img, rig, eye, p.x.round() as i64, p.y.round() as i64)
}

/// Per eye: the camera and `cam_from_model`.
fn eyes(rig: &StereoRig, left_from_model: &Isometry3<f64>) -> [(Intrinsics, Isometry3<f64>); 2] {
    [
        (rig.left, *left_from_model),
        (rig.right, rig.right_from_left * left_from_model),
    ]
}

/// Sub-pixel edge position from the red coverage along a row/column scan, compared with
/// the forward projection of the card edge at that row/column.
fn check_edges(img: &RgbImage, rig: &StereoRig, left_from_model: &Isometry3<f64>, size: [f64; 2]) {
    let (hl, hb) = (size[0] / 2.0, size[1] / 2.0);
    for (eye, (cam, cfm)) in eyes(rig, left_from_model).iter().enumerate() {
        let proj = |x: f64, y: f64| cam.project(&(cfm * Point3::new(x, y, 0.0))).unwrap();
        let c = proj(0.0, 0.0);
        // Edges as (corner A, corner B) in model coordinates.
        let edges = [
            ([hl, -hb], [hl, hb]),
            ([-hl, -hb], [-hl, hb]),
            ([-hl, hb], [hl, hb]),
            ([-hl, -hb], [hl, -hb]),
        ];
        for (a, b) in edges {
            let m = proj(0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1]));
            let horizontal = (m.x - c.x).abs() > (m.y - c.y).abs();
            // Scan line through the projected edge midpoint, from the card centre outwards.
            let line = if horizontal { m.y.round() } else { m.x.round() };
            let (start, end) = if horizontal { (c.x, m.x) } else { (c.y, m.y) };
            let step: i64 = if end > start { 1 } else { -1 };
            let mut s = start.round() as i64;
            let s0 = s;
            let mut coverage = 0.0;
            for _ in 0..2000 {
                let p = if horizontal {
                    pixel(img, rig, eye, s, line as i64)
                } else {
                    pixel(img, rig, eye, line as i64, s)
                };
                let alpha = p[0] as f64 / 255.0;
                if alpha < 1e-6 {
                    break;
                }
                coverage += alpha;
                s += step;
            }
            let measured = s0 as f64 - 0.5 * step as f64 + coverage * step as f64;
            // Forward projection: the edge point whose projection lies on the scan line.
            let (mut lo, mut hi) = (0.05, 0.95);
            let on_edge = |t: f64| proj(a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]));
            let f = |t: f64| {
                let q = on_edge(t);
                (if horizontal { q.y } else { q.x }) - line
            };
            assert!(f(lo) * f(hi) < 0.0, "scan line misses the edge");
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                if f(lo) * f(mid) <= 0.0 {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            let q = on_edge(0.5 * (lo + hi));
            let expected = if horizontal { q.x } else { q.y };
            assert!(
                (measured - expected).abs() < 0.3,
                "eye {eye} edge {a:?}-{b:?}: measured {measured:.3}, projected {expected:.3}"
            );
        }
        // Corners: 2 px inside (towards the centre) is card, 2 px outside is wall.
        for (x, y) in [(hl, hb), (-hl, hb), (hl, -hb), (-hl, -hb)] {
            let p = proj(x, y);
            let dir = (c - p).normalize();
            assert_eq!(at(img, rig, eye, p + 2.0 * dir), RED, "eye {eye} inside {x},{y}");
            assert_eq!(at(img, rig, eye, p - 2.0 * dir), BLUE, "eye {eye} outside {x},{y}");
        }
    }
}

fn check_centre(img: &RgbImage, rig: &StereoRig, left_from_model: &Isometry3<f64>, colour: [u8; 3]) {
    for (eye, (cam, cfm)) in eyes(rig, left_from_model).iter().enumerate() {
        let c = cam.project(&(cfm * Point3::origin())).unwrap();
        assert_eq!(at(img, rig, eye, c), colour, "eye {eye}");
    }
}

#[test]
fn card_centre_and_edges_match_projection_pinhole() {
    let rig = rig(false);
    let size = [120.0, 90.0];
    let lfm = pose([15.0, -10.0, 600.0], [0.2, -0.3, 0.15]);
    let img = render(&rig, &left_from_hand(), &scene_with(lfm, RED, size));
    assert_eq!(img.dimensions(), (1280, 360));
    check_centre(&img, &rig, &lfm, RED);
    check_edges(&img, &rig, &lfm, size);
}

#[test]
fn card_geometry_matches_projection_with_distortion() {
    let rig = rig(true);
    // Large and off-centre: the corners land where distortion is strong.
    let size = [220.0, 160.0];
    let lfm = pose([140.0, 40.0, 550.0], [-0.25, 0.35, -0.1]);
    let img = render(&rig, &left_from_hand(), &scene_with(lfm, RED, size));
    check_centre(&img, &rig, &lfm, RED);
    check_edges(&img, &rig, &lfm, size);
}

#[test]
fn texture_is_upright_and_unmirrored() {
    // Four-quadrant texture: top-left red, top-right green, bottom-left blue, bottom-right white.
    let tex = RgbImage::from_fn(64, 48, |x, y| match (x < 32, y < 24) {
        (true, true) => Rgb([255, 0, 0]),
        (false, true) => Rgb([0, 255, 0]),
        (true, false) => Rgb([0, 0, 255]),
        (false, false) => Rgb([255, 255, 255]),
    });
    let rig = rig(false);
    let lfm = pose([0.0, 0.0, 500.0], [0.0, 0.0, 0.0]);
    let mut scene = scene_with(lfm, RED, [100.0, 80.0]);
    scene.card.texture = tex;
    scene.background = Background::solid([0, 0, 0], 1500.0);
    let img = render(&rig, &left_from_hand(), &scene);
    let q = |x: f64, y: f64| at(&img, &rig, 0, rig.left.project(&Point3::new(x, y, 500.0)).unwrap());
    assert_eq!(q(-25.0, -20.0), [255, 0, 0]);
    assert_eq!(q(25.0, -20.0), [0, 255, 0]);
    assert_eq!(q(-25.0, 20.0), [0, 0, 255]);
    assert_eq!(q(25.0, 20.0), [255, 255, 255]);
}

#[test]
fn back_face_shows_cardboard_not_texture() {
    let rig = rig(false);
    // Rotated half a turn about model y: the camera now sees the +z_M face.
    let lfm = Isometry3::from_parts(
        Translation3::new(0.0, 0.0, 600.0),
        UnitQuaternion::from_axis_angle(&Vector3::y_axis(), std::f64::consts::PI),
    );
    let img = render(&rig, &left_from_hand(), &scene_with(lfm, RED, [120.0, 90.0]));
    check_centre(&img, &rig, &lfm, CARDBOARD);
    assert!(img.pixels().all(|p| p.0 != RED));
}

fn grey_scene(noise: f64, seed: u64) -> Scene {
    let mut s = scene_with(pose([0.0, 0.0, 600.0], [0.1, 0.2, 0.0]), [120, 130, 140], [120.0, 90.0]);
    s.background = Background::solid([90, 100, 110], 1500.0);
    s.noise_sigma = noise;
    s.seed = seed;
    s
}

#[test]
fn seeded_noise_is_deterministic() {
    let rig = rig(true);
    let lfh = left_from_hand();
    let a = render(&rig, &lfh, &grey_scene(5.0, 1));
    let b = render(&rig, &lfh, &grey_scene(5.0, 1));
    let c = render(&rig, &lfh, &grey_scene(5.0, 2));
    let clean = render(&rig, &lfh, &grey_scene(0.0, 1));
    assert_eq!(a, b);
    assert_ne!(a, c);
    let n = a.as_raw().len() as f64;
    let mean_abs: f64 = a
        .as_raw()
        .iter()
        .zip(clean.as_raw())
        .map(|(&x, &y)| (x as f64 - y as f64).abs())
        .sum::<f64>()
        / n;
    // E|N(0, 5)| ≈ 3.99 (plus rounding).
    assert!((mean_abs - 4.0).abs() < 0.3, "{mean_abs}");
}

#[test]
fn brightness_scales_card_only() {
    let rig = rig(false);
    let lfm = pose([0.0, 0.0, 600.0], [0.0, 0.0, 0.0]);
    let mut scene = scene_with(lfm, [200, 100, 40], [120.0, 90.0]);
    scene.brightness = 0.5;
    let img = render(&rig, &left_from_hand(), &scene);
    check_centre(&img, &rig, &lfm, [100, 50, 20]);
    assert_eq!(pixel(&img, &rig, 0, 2, 2), BLUE);
}

fn count_red(img: &RgbImage, rig: &StereoRig) -> usize {
    (0..rig.height)
        .flat_map(|y| (0..rig.width).map(move |x| (x, y)))
        .filter(|&(x, y)| img.get_pixel(x, y).0 == RED)
        .count()
}

#[test]
fn occluder_hides_requested_fraction() {
    let rig = rig(false);
    let lfh = left_from_hand();
    for (seed, (fraction, euler)) in [
        (0.3, [0.0, 0.0, 0.0]),
        (0.5, [0.1, 0.3, 0.2]),
        (0.15, [0.3, 0.0, -0.2]),
        (0.4, [0.0, -0.3, 0.0]),
    ]
    .into_iter()
    .enumerate()
    {
        let size = [150.0, 110.0];
        let lfm = pose([10.0, 5.0, 600.0], euler);
        let mut scene = scene_with(lfm, RED, size);
        let full = count_red(&render(&rig, &lfh, &scene), &rig) as f64;
        scene.occluder = Occluder::covering(&lfm, size, fraction, OccluderFill::Solid([0, 200, 0]), seed as u64);
        assert!(scene.occluder.is_some());
        let img = render(&rig, &lfh, &scene);
        let left = count_red(&img, &rig) as f64;
        let hidden = 1.0 - left / full;
        assert!(
            (hidden - fraction).abs() < 0.04,
            "seed {seed}: hidden {hidden:.3}, wanted {fraction}"
        );
        assert!(img.pixels().any(|p| p.0 == [0, 200, 0]));
    }
    let lfm = pose([0.0, 0.0, 600.0], [0.0, 0.0, 0.0]);
    assert!(Occluder::covering(&lfm, [100.0, 80.0], 0.0, OccluderFill::Solid([0; 3]), 0).is_none());
    assert!(Occluder::covering(&lfm, [-1.0, 80.0], 0.5, OccluderFill::Solid([0; 3]), 0).is_none());
}

#[test]
fn collage_background_and_degenerate_inputs_do_not_panic() {
    let rig = rig(true);
    let lfm = pose([0.0, 0.0, 600.0], [0.0, 0.0, 0.0]);
    let mut scene = scene_with(lfm, RED, [120.0, 90.0]);
    scene.background = Background::collage(&[], 5, 1500.0);
    scene.occluder = Occluder::covering(
        &lfm,
        [120.0, 90.0],
        0.2,
        OccluderFill::Texture(RgbImage::from_pixel(8, 8, Rgb([9, 9, 9]))),
        3,
    );
    let img = render(&rig, &left_from_hand(), &scene);
    check_centre(&img, &rig, &lfm, RED);
    // Degenerate: empty texture, NaN size, camera inside nothing, zero-size rig.
    scene.card.texture = RgbImage::new(0, 0);
    scene.card.size_mm = [f64::NAN, 10.0];
    scene.brightness = f64::NAN;
    scene.noise_sigma = -3.0;
    let _ = render(&rig, &left_from_hand(), &scene);
    let mut empty = rig.clone();
    empty.width = 0;
    assert_eq!(render(&empty, &left_from_hand(), &scene).dimensions(), (0, 360));
}

#[test]
fn incremental_frames_equal_full_renders() {
    let rig = rig(true);
    let lfm = pose([-20.0, 10.0, 600.0], [0.3, -0.2, 0.4]);
    let mut scene = scene_with(lfm, RED, [120.0, 90.0]);
    scene.card.texture = RgbImage::from_fn(40, 30, |x, y| Rgb([6 * x as u8, 8 * y as u8, 90]));
    scene.background = Background::collage(&[], 5, 1500.0);
    scene.occluder = Occluder::covering(&lfm, [120.0, 90.0], 0.2, OccluderFill::Solid([9, 200, 9]), 3);
    let mut renderer = Renderer::new(&rig, &left_from_hand(), &scene);
    let mut out = vec![0u8; renderer.frame_len()];
    for step in 0..3 {
        let moved = pose(
            [-20.0 + 25.0 * step as f64, 10.0, 600.0 - 30.0 * step as f64],
            [0.3, -0.2, 0.4 + 0.2 * step as f64],
        );
        scene.card.hand_from_model = left_from_hand().inverse() * moved;
        renderer.render_into(&scene, &mut out);
        let full = render(&rig, &left_from_hand(), &scene);
        let differ = out.iter().zip(full.as_raw()).filter(|(a, b)| a != b).count();
        assert_eq!(differ, 0, "step {step}: {differ} bytes differ from a full render");
    }
}
