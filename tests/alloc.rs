//! Steady-state work allocates nothing: a counting global allocator (this test binary's
//! own) watches a tracking frame of the estimator and a frame of the synthetic camera.

// Test code: a failed unwrap is a failed test.
#![allow(clippy::unwrap_used)]

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use nalgebra::{Isometry3, Translation3};
use photopose::camera::calibration::Resolution;
use photopose::config::Config;
use photopose::estimator::model::PhotoModel;
use photopose::estimator::tracking::StreamTracker;
use photopose::render::{Renderer, SceneSpec};
use photopose::vision::lookup::SbsBytes;
use photopose::vision::PixelFormat;

use common::{data, repo};
use photopose::vision::color::yuyv_from_rgb;

/// Counts every allocation of every thread.
struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocations() -> usize {
    ALLOCATIONS.load(Ordering::Relaxed)
}

/// Both checks in one test: the counter is global, so nothing else may run meanwhile.
#[test]
fn tracking_frames_and_synthetic_frames_allocate_nothing() {
    let config = Config::load(None).expect("config");
    let spec = SceneSpec::load(&repo("config/scenes/rocket.toml")).expect("scene");
    let mut scene = spec.build(&config.left_from_hand).expect("scene");
    let rig = config.calibration.rig(Resolution::HD).expect("HD");
    let mut renderer = Renderer::new(&rig, &config.left_from_hand, &scene);
    let start = scene.card.hand_from_model;
    let moved = |i: usize| Translation3::new(2.0 * i as f64, -(i as f64), 0.5 * i as f64) * start;
    // A few frames of the card moving 2–3 mm per frame.
    let mut frames = vec![vec![0u8; renderer.frame_len()]; 8];
    for (i, f) in frames.iter_mut().enumerate() {
        scene.card.hand_from_model = moved(i);
        renderer.render_into(&scene, f);
    }
    let (width, height) = (rig.width as usize, rig.height as usize);
    let frame = |bytes| SbsBytes {
        bytes,
        width,
        height,
        row_stride: width * 6,
        format: PixelFormat::Rgb8,
    };
    // The same frames as a ZED sends them.
    let yuyv: Vec<Vec<u8>> = frames.iter().map(|f| yuyv_from_rgb(f, width)).collect();
    let yuyv_frame = |bytes| SbsBytes {
        bytes,
        width,
        height,
        row_stride: width * 4,
        format: PixelFormat::Yuyv,
    };

    // The synthetic camera: a frame after the first renders without allocating.
    let mut out = vec![0u8; renderer.frame_len()];
    scene.card.hand_from_model = moved(9);
    renderer.render_into(&scene, &mut out);
    let before = allocations();
    for i in 10..14 {
        scene.card.hand_from_model = moved(i);
        renderer.render_into(&scene, &mut out);
    }
    let rendering = allocations() - before;

    // The estimator: acquisition and the first tracking frames may allocate (buffers
    // grow to their working size); the frames after that may not. Then the same frames
    // as YUYV, converted straight from the payload.
    let truth: Isometry3<f64> = moved(frames.len() - 1);
    let track = |frames: Vec<SbsBytes>| {
        let model = PhotoModel::load(&data("examples/rocket.model")).expect("model");
        let mut tracker = StreamTracker::new(model, config.clone());
        for f in &frames[..4] {
            tracker.prepare(f).expect("frame");
            tracker.step().expect("estimate");
        }
        let before = allocations();
        let mut last = None;
        for f in &frames[4..] {
            tracker.prepare(f).expect("frame");
            last = tracker.step();
        }
        let allocated = allocations() - before;
        let est = last.expect("estimate");
        (allocated, (est.best.position - truth.translation.vector).norm())
    };
    let (tracking, err) = track(frames.iter().map(|f| frame(f.as_slice())).collect());
    let (tracking_yuyv, err_yuyv) = track(yuyv.iter().map(|f| yuyv_frame(f.as_slice())).collect());
    println!(
        "allocations: {rendering} in 4 synthetic frames, {tracking} in 4 tracking frames (last error {err:.1} mm), \
         {tracking_yuyv} in 4 YUYV tracking frames (last error {err_yuyv:.1} mm)"
    );
    assert!(err < 10.0, "tracking went wrong: {err:.1} mm");
    assert!(err_yuyv < 10.0, "tracking YUYV went wrong: {err_yuyv:.1} mm");
    assert_eq!(rendering, 0, "the synthetic camera allocated per frame");
    assert_eq!(tracking, 0, "the tracking loop allocated per frame");
    assert_eq!(tracking_yuyv, 0, "the tracking loop allocated per YUYV frame");
}
