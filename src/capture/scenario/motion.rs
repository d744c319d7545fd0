//! The takes: what moves, how fast, in what light and behind what. Poses are in the left
//! camera's frame (mm), times in seconds from the first frame.

use std::f64::consts::TAU;

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use super::{CardPhoto, Scenario};
use crate::render::{Occluder, OccluderFill};

const fn card(photo: &'static str, bbox: [u32; 4]) -> CardPhoto {
    CardPhoto { photo, bbox }
}

const CUP: CardPhoto = card("tests/data/photos/coffee.jpg", [149, 22, 279, 289]);
const CAT: CardPhoto = card("tests/data/photos/chelsea.jpg", [70, 20, 280, 270]);
const ASTRO: CardPhoto = card("tests/data/photos/astronaut.jpg", [120, 20, 270, 330]);
const ROCKET: CardPhoto = card("tests/data/photos/rocket.jpg", [150, 60, 340, 300]);
const BOWL: CardPhoto = card("tests/data/photos/bowl.jpg", [230, 110, 520, 380]);
const HOPPER: CardPhoto = card("tests/data/photos/hopper.jpg", [100, 20, 340, 480]);

/// A card at `position` (mm), turned about x, then y, then z (degrees).
fn pose(position: [f64; 3], deg: [f64; 3]) -> Isometry3<f64> {
    let q = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), deg[0].to_radians())
        * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), deg[1].to_radians())
        * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), deg[2].to_radians());
    Isometry3::from_parts(Translation3::new(position[0], position[1], position[2]), q)
}

/// The sweep: ±180 mm side to side at up to 600 mm/s (ω = 3.33 rad/s), 0.55–0.85 m deep,
/// turning ±18° about the vertical at up to 60°/s.
fn sweep(t: f64) -> Isometry3<f64> {
    let w = 600.0 / 180.0;
    pose(
        [
            180.0 * (w * t).sin(),
            30.0 * (0.5 * w * t).sin(),
            700.0 + 150.0 * (0.4 * w * t).cos(),
        ],
        [15.0, 18.0 * (w * t).sin(), 5.0],
    )
}

/// The sweep at half speed.
fn half_sweep(t: f64) -> Isometry3<f64> {
    sweep(0.5 * t)
}

/// A slow loop: ±60 × ±30 mm at up to about 100 mm/s, 0.6–0.7 m deep, gently turning.
fn slow(t: f64) -> Isometry3<f64> {
    let w = TAU / 4.0;
    pose(
        [
            60.0 * (w * t).sin(),
            30.0 * (2.0 * w * t).sin(),
            650.0 + 50.0 * (w * t).cos(),
        ],
        [-10.0 + 5.0 * (w * t).sin(), 12.0, -8.0],
    )
}

/// Side to side at up to 260 mm/s for 2 s, out of view to the right for 1.5 s, then back
/// in from the left at 260 mm/s.
fn leave(t: f64) -> Isometry3<f64> {
    let w = 260.0 / 150.0;
    let x = if t < 2.0 {
        150.0 * (w * t).sin()
    } else if t < 3.5 {
        900.0
    } else {
        -700.0 + 260.0 * (t - 3.5)
    };
    pose([x, 20.0, 600.0], [10.0, -10.0, 0.0])
}

/// From 1.0 m to 0.33 m in 4 s while the tilt goes from 30° to 0, then held.
fn approach(t: f64) -> Isometry3<f64> {
    let s = (t / 4.0).min(1.0);
    pose(
        [40.0 - 40.0 * s, -30.0 + 20.0 * s, 1000.0 - 670.0 * s],
        [30.0 * (1.0 - s), 0.0, 10.0],
    )
}

/// The same light all along.
fn steady(_: f64) -> [f64; 3] {
    [1.0; 3]
}

/// Brightness 0.55–1.45× (a 3 s cycle) and a white balance drifting warm and cool (4.5 s).
fn changing(t: f64) -> [f64; 3] {
    let b = 1.0 + 0.45 * (TAU * t / 3.0).sin();
    let wb = 0.15 * (TAU * t / 4.5).sin();
    [b * (1.0 + wb), b, b * (1.0 - wb)]
}

/// Nothing in the way.
fn clear(_: f64, _: &Isometry3<f64>, _: [f64; 2]) -> Option<Occluder> {
    None
}

/// A slab `size_mm` parallel to the card, 100 mm in front of it, centred at `offset` (mm,
/// along the card's axes).
fn slab(card: &Isometry3<f64>, offset: [f64; 2], size_mm: [f64; 2], colour: [u8; 3]) -> Occluder {
    let shift = Translation3::new(offset[0], offset[1], 0.0);
    let toward_camera = Translation3::from(-100.0 * card.translation.vector.normalize());
    Occluder {
        left_from_occluder: toward_camera * *card * shift,
        size_mm,
        fill: OccluderFill::Solid(colour),
    }
}

/// A forearm (skin, 70 mm wide) sweeps across the card from left to right during
/// 1–2.5 s; a grey board slides in from the right during 3–4 s, covering up to about 55 %
/// of the card, and withdraws by 5 s.
fn occlude(t: f64, card: &Isometry3<f64>, size: [f64; 2]) -> Option<Occluder> {
    const SKIN: [u8; 3] = [214, 160, 130];
    const GREY: [u8; 3] = [128, 128, 128];
    if (1.0..2.5).contains(&t) {
        let x = -size[0] + 2.0 * size[0] * (t - 1.0) / 1.5;
        return Some(slab(card, [x, 0.0], [70.0, 500.0], SKIN));
    }
    let cover = if (3.0..4.0).contains(&t) {
        0.55 * (t - 3.0)
    } else if (4.0..5.0).contains(&t) {
        0.55 * (5.0 - t)
    } else {
        return None;
    };
    // The board's left edge at the share `cover` of the card from its right edge (the
    // slab is nearer the camera, so it hides a little more than that).
    let edge = 0.5 * size[0] - cover * size[0];
    Some(slab(card, [edge + 150.0, 0.0], [300.0, 400.0], GREY))
}

/// Every take.
#[rustfmt::skip]
pub fn takes() -> Vec<Scenario> {
    let take = |name, card, wall, length_mm, fps, motion| Scenario {
        name, card, wall, length_mm, fps, seconds: 4.0, exposure_s: 0.0, motion,
        light: steady, occluder: clear, noise: 0.0, yuyv: false, hand_eye: false,
    };
    vec![
        Scenario { exposure_s: 1.0 / 60.0, hand_eye: true, ..take("sweep", ROCKET, "tests/data/backgrounds/room.jpg", 110.0, 30.0, sweep) },
        Scenario { exposure_s: 1.0 / 120.0, ..take("sweep-60fps", BOWL, "tests/data/backgrounds/marigold.jpg", 120.0, 60.0, sweep) },
        Scenario { exposure_s: 1.0 / 60.0, yuyv: true, noise: 3.0, ..take("yuyv", CAT, "tests/data/backgrounds/brushes.jpg", 110.0, 30.0, half_sweep) },
        Scenario { light: changing, seconds: 5.0, ..take("light", CUP, "tests/data/backgrounds/creek.jpg", 100.0, 30.0, slow) },
        Scenario { occluder: occlude, seconds: 6.0, ..take("occlude", ASTRO, "tests/data/backgrounds/dogs.jpg", 120.0, 30.0, slow) },
        Scenario { seconds: 6.0, ..take("leave", HOPPER, "tests/data/backgrounds/boats.jpg", 90.0, 30.0, leave) },
        Scenario { seconds: 5.0, hand_eye: true, ..take("approach", ROCKET, "tests/data/backgrounds/cups.jpg", 110.0, 30.0, approach) },
    ]
}
