//! `cargo bench --bench render`: the synthetic camera's renderer on its default scene
//! (`config/scenes/rocket.toml`: the rocket card in front of the collage wall, with pixel
//! noise) through the example calibration at HD.
//!
//! Throughput is in output pixels (both eyes).

// Test code: a failed unwrap is a failed test.
#![allow(clippy::unwrap_used)]

#[path = "../tests/common/mod.rs"]
mod common;

use std::cell::Cell;

use divan::counter::ItemsCount;
use divan::{black_box, Bencher};
use nalgebra::{Isometry3, Translation3};
use photopose::camera::calibration::Resolution;
use photopose::camera::StereoRig;
use photopose::config::Config;
use photopose::render::{self, Renderer, Scene, SceneSpec};

fn main() {
    divan::main();
}

/// The synthetic camera's scene, the HD rig and the hand-eye transform.
fn fixture() -> (Scene, StereoRig, Isometry3<f64>) {
    let config = Config::load(None).expect("built-in configuration");
    let spec = SceneSpec::load(&common::repo("config/scenes/rocket.toml")).expect("scene");
    let scene = spec.build(&config.left_from_hand).expect("scene");
    let rig = config.calibration.rig(Resolution::HD).expect("HD");
    (scene, rig, config.left_from_hand)
}

fn pixels(rig: &StereoRig) -> ItemsCount {
    ItemsCount::new(2 * rig.width as usize * rig.height as usize)
}

/// A whole frame rendered on all cores, the cameras' ray tables already cached.
#[divan::bench]
fn full_frame(bencher: Bencher) {
    let (scene, rig, left_from_hand) = fixture();
    let mut out = vec![0u8; 2 * rig.width as usize * rig.height as usize * 3];
    render::render_into(&rig, &left_from_hand, &scene, &mut out);
    bencher
        .counter(pixels(&rig))
        .bench_local(|| render::render_into(&rig, &left_from_hand, black_box(&scene), &mut out));
}

/// The first frame of a camera: its ray tables (the lens distortion inverted at every
/// pixel corner) are built before it renders. Each iteration gets a camera of its own.
#[divan::bench(sample_count = 20, sample_size = 1)]
fn first_frame_of_a_camera(bencher: Bencher) {
    let (scene, rig, left_from_hand) = fixture();
    let mut out = vec![0u8; 2 * rig.width as usize * rig.height as usize * 3];
    let cameras = Cell::new(0u32);
    bencher
        .counter(pixels(&rig))
        .with_inputs(|| {
            cameras.set(cameras.get() + 1);
            let mut fresh = rig.clone();
            // A shift far below a pixel: another camera to the ray-table cache.
            fresh.left.cx += 1e-6 * f64::from(cameras.get());
            fresh.right.cx += 1e-6 * f64::from(cameras.get());
            fresh
        })
        .bench_local_refs(|fresh| render::render_into(fresh, &left_from_hand, black_box(&scene), &mut out));
}

/// A frame of the moving card as `photopose capture` renders it: the wall copied, only
/// the pixels around the card re-rendered, on one thread.
#[divan::bench]
fn moving_card_frame(bencher: Bencher) {
    let (mut scene, rig, left_from_hand) = fixture();
    let mut renderer = Renderer::new(&rig, &left_from_hand, &scene);
    let mut out = vec![0u8; renderer.frame_len()];
    let start = scene.card.hand_from_model;
    let mut frame = 0u32;
    bencher.counter(pixels(&rig)).bench_local(|| {
        // 1 mm a frame to the right and back, over 60 frames.
        frame = (frame + 1) % 60;
        let x = f64::from(frame.min(60 - frame));
        scene.card.hand_from_model = Translation3::new(x, 0.0, 0.0) * start;
        renderer.render_into(black_box(&scene), &mut out);
    });
}
