//! The tracking GA on a rendered moving target, in process: acquisition on the first
//! frame, then one step per frame at 60 fps while the card moves at 150 mm/s; and the
//! same frames and seed give bit-identical poses.

use std::path::Path;
use std::time::Instant;

use image::RgbImage;
use nalgebra::{Isometry3, Translation3, Vector3};
use photopose::camera::calibration::{Calibration, Resolution};
use photopose::camera::StereoRig;
use photopose::capture::synthetic::SyntheticSource;
use photopose::capture::{FrameSource, Truth};
use photopose::cli::estimator::pose_msg;
use photopose::cli::report::stats::Samples;
use photopose::config::Config;
use photopose::estimator::model::PhotoModel;
use photopose::estimator::pose::PoseSize;
use photopose::estimator::tracking::{Estimate, StreamTracker, TrackState, RELOCATE_GENERATIONS};
use photopose::estimator::verify::tilt_disparity_px;
use photopose::render::{self, Background, Card, Scene};
use photopose::transport::messages::PoseMsg;
use photopose::transport::messages::Status;
use photopose::vision::lookup::SbsBytes;
use photopose::vision::PixelFormat;

use crate::scenes::{self, photo, rotation, PHOTOS};

/// The rocket card of scene `rocket-650-30` in front of the collage wall, with the
/// scene's spec, the rendered scene's configuration and model, and the HD rig.
fn rocket_scene() -> (scenes::Spec, scenes::Rendered, StereoRig, Scene) {
    let spec = scenes::all()
        .into_iter()
        .find(|s| s.name == "rocket-650-30")
        .expect("scene");
    let r = scenes::render(&spec, 3);
    let rig = r
        .config
        .calibration
        .rig(photopose::camera::calibration::Resolution::HD)
        .expect("HD");
    let full = photo(spec.photo);
    let [x, y, w, h] = spec.bbox;
    let background: Vec<_> = PHOTOS.iter().filter(|p| **p != spec.photo).map(|p| photo(p)).collect();
    let scene = Scene {
        card: Card {
            texture: image::imageops::crop_imm(&full, x as u32, y as u32, w as u32, h as u32).to_image(),
            hand_from_model: r.hand_from_model,
            size_mm: spec.size_mm,
        },
        background: Background::collage(&background, 3, 1600.0),
        noise_sigma: 0.0,
        brightness: 1.0,
        occluder: None,
        seed: 3,
    };
    (spec, r, rig, scene)
}

/// A rendered side-by-side RGB image of `rig` as the tracker reads frames.
fn sbs_frame<'a>(rig: &StereoRig, sbs: &'a RgbImage) -> SbsBytes<'a> {
    SbsBytes {
        bytes: sbs.as_raw(),
        width: rig.width as usize,
        height: rig.height as usize,
        row_stride: sbs.width() as usize * 3,
        format: PixelFormat::Rgb8,
    }
}

/// Renders `scene` and runs one tracker step on it: the estimate and the step's time, ms
/// (rendering excluded).
fn step(tracker: &mut StreamTracker, rig: &StereoRig, r: &scenes::Rendered, scene: &Scene) -> (Estimate, f64) {
    let sbs = render::render(rig, &r.config.left_from_hand, scene);
    let start = Instant::now();
    tracker.prepare(&sbs_frame(rig, &sbs)).expect("HD frame");
    let est = tracker.step().expect("a prepared frame");
    (est, start.elapsed().as_secs_f64() * 1e3)
}

/// Frame rate and card speed of the moving-card tests.
const FPS: f64 = 60.0;
const SPEED_MM_S: f64 = 150.0;

/// The card of `rocket_scene` at frame `i` of a pass at [`SPEED_MM_S`] filmed at
/// [`FPS`], moving diagonally in the left-camera frame and slowly turning:
/// `hand_from_model`.
fn moving_card(spec: &scenes::Spec, r: &scenes::Rendered, i: usize) -> Isometry3<f64> {
    let t = i as f64 / FPS;
    let along = Vector3::new(0.8, 0.5, 0.33).normalize() * (SPEED_MM_S * t);
    let left_from_model = Isometry3::from_parts(
        Translation3::from(Vector3::from(spec.position) + along - Vector3::new(60.0, 40.0, 0.0)),
        rotation([spec.rotation_deg[0], 0.0, 20.0 * t]),
    );
    r.config.left_from_hand.inverse() * left_from_model
}

/// Position error (mm) of the tracked model origin on every frame of a 150 mm/s pass.
#[test]
fn tracks_a_card_moving_at_150_mm_per_s() {
    let (spec, r, rig, mut scene) = rocket_scene();
    let frames = 40;
    let mut tracker = StreamTracker::new(r.model.clone(), r.config.clone());
    let (mut errors, mut times) = (Vec::new(), Vec::new());
    for i in 0..frames {
        scene.card.hand_from_model = moving_card(&spec, &r, i);
        let (est, ms) = step(&mut tracker, &rig, &r, &scene);
        times.push(ms);
        let err = (est.best.position - scene.card.hand_from_model.translation.vector).norm();
        if i == 0 {
            assert!(err < 10.0, "acquisition ends {err:.1} mm off");
            // The verdict finds the quick pass's result: no search (0 generations).
            assert_eq!(est.generations, 0, "the acquisition's quick pass taken");
        } else if i == 1 {
            // The acquired model is relocated on the first frame after it.
            assert_eq!(est.generations as usize, RELOCATE_GENERATIONS);
            assert_eq!(est.state, TrackState::Tracking, "relocation: F {:.3}", est.fitness.f);
            errors.push(err);
        } else {
            assert_eq!(est.generations as usize, r.config.tracking.generations_per_frame);
            assert_eq!(est.state, TrackState::Tracking, "frame {i}: F {:.3}", est.fitness.f);
            errors.push(err);
        }
    }
    let acquisition = times.remove(0);
    times.sort_by(f64::total_cmp);
    println!(
        "acquisition {acquisition:.0} ms, tracking frame p50 {:.2} ms, max {:.2} ms",
        times[times.len() / 2],
        times.last().unwrap()
    );
    errors.sort_by(f64::total_cmp);
    let p95 = errors[(errors.len() as f64 * 0.95).ceil() as usize - 1];
    println!(
        "tracking at {SPEED_MM_S} mm/s: median {:.1} mm, p95 {p95:.1} mm, max {:.1} mm over {} frames",
        errors[errors.len() / 2],
        errors.last().unwrap(),
        errors.len()
    );
    assert!(p95 <= 10.0, "p95 tracking error {p95:.1} mm");
}

/// A card that recedes until the stereo pair cannot resolve its tilt is followed but no
/// longer called `tracking`. The rig's baseline is narrowed to 40 mm so that this
/// happens inside the search space: the rocket card's 159 mm side then changes the
/// disparity by 1.2 px per 10° of tilt at about 0.8 m, the verdict's least.
#[test]
fn a_card_whose_tilt_is_not_resolved_is_followed_but_not_tracking() {
    let (spec, mut r, _, mut scene) = rocket_scene();
    let conf = crate::common::repo("config/SN-example.conf");
    let text = std::fs::read_to_string(&conf)
        .unwrap()
        .replace("Baseline=119.934", "Baseline=40");
    r.config.calibration = Calibration::parse(&text, &conf).unwrap();
    let rig = r.config.calibration.rig(Resolution::HD).unwrap();
    let mut tracker = StreamTracker::new(r.model.clone(), r.config.clone());
    let left_from_start = r.config.left_from_hand * r.hand_from_model;
    let (mut tracked, mut followed) = (0, 0);
    for i in 0..80 {
        // 4 mm further a frame along the line of sight, 650 → 966 mm.
        let z = spec.position[2] + 4.0 * i as f64;
        let mut left_from_model = left_from_start;
        left_from_model.translation.vector *= z / spec.position[2];
        scene.card.hand_from_model = r.config.left_from_hand.inverse() * left_from_model;
        let (est, _) = step(&mut tracker, &rig, &r, &scene);
        let truth = PoseSize::from_pose(&scene.card.hand_from_model, spec.size_mm, r.model.l_p, r.model.b_p);
        let tilt_px = tilt_disparity_px(&truth, [r.model.l_p, r.model.b_p], &rig, &r.config.left_from_hand);
        let err = (est.best.position - truth.position).norm();
        if i == 0 {
            // The acquisition's quick pass ends on the rocket's sky, 125 mm long for
            // 180, unfound; a size sweep grows it, so the search runs
            // (`quick::size_settled`). Taken, it was followed at that length and not
            // `tracking`: the short model's tilt disparity is below the verdict's.
            assert_eq!(
                est.generations as usize, r.config.tracking.acquire_generations,
                "frame 0: the search"
            );
        }
        if i > 0 && tilt_px >= 1.4 {
            assert_eq!(
                est.state,
                TrackState::Tracking,
                "{z:.0} mm, {tilt_px:.2} px: {err:.1} mm off"
            );
            tracked += 1;
        } else if tilt_px < 1.0 {
            assert_eq!(
                est.state,
                TrackState::Searching,
                "{z:.0} mm, {tilt_px:.2} px: {err:.1} mm off"
            );
            assert!(err < 30.0, "{z:.0} mm: not followed, {err:.1} mm off");
            followed += 1;
        }
    }
    assert!(
        tracked >= 10 && followed >= 10,
        "{tracked} tracked, {followed} followed"
    );
}

/// The card vanishes: every pose stays sound (finite, unit quaternion), and a pose whose
/// `F` is below `[tracking] lost_fitness` is `lost` at once, never `tracking`.
#[test]
fn a_pose_below_the_fitness_floor_is_lost_never_tracking() {
    let (_, r, rig, mut scene) = rocket_scene();
    let settings = r.config.tracking.clone();
    let mut tracker = StreamTracker::new(r.model.clone(), r.config.clone());
    let mut statuses = Vec::new();
    for i in 0..12 {
        if i == 3 {
            // Out of both cameras' view: only the wall is left.
            scene.card.hand_from_model = Isometry3::translation(5000.0, 0.0, 650.0);
        }
        let (est, _) = step(&mut tracker, &rig, &r, &scene);
        let pose = pose_msg(tracker.model(), &est, i, 0);
        assert!(pose.is_sound(), "frame {i}: {pose:?}");
        let f = pose.fitness;
        if f < settings.lost_fitness {
            assert_eq!(pose.status, Status::Lost as u32, "frame {i}: F {f:.3} below the floor");
        }
        if f < settings.min_fitness {
            assert_ne!(pose.status, Status::Tracking as u32, "frame {i}: F {f:.3}");
        }
        statuses.push((pose.status, f));
    }
    println!("status and F per frame: {statuses:?}");
    // Frame 0's acquisition ends at a quick pass the verdict does not find (measured:
    // `searching`, F 1.26); the relocation on frame 1 is `tracking` (F 1.94).
    assert!(
        statuses[1..3].iter().all(|(s, _)| *s == Status::Tracking as u32),
        "{statuses:?}"
    );
    // Long before `lost_after_frames` (30) searching frames, the floor already says lost.
    assert!(
        statuses[3..].iter().any(|(s, _)| *s == Status::Lost as u32),
        "{statuses:?}"
    );
}

/// The card leaves the view for a second and comes back 150 mm further on: never
/// `tracking` while it is away; once lost, the tracker relocates the last tracked pose on
/// each frame (and acquires afresh after `RECOVERIES` of them), so the card is
/// `tracking` again within 2 frames of coming back, and right.
#[test]
fn a_card_that_leaves_and_comes_back_is_recovered_at_once() {
    let (spec, r, rig, mut scene) = rocket_scene();
    let (away, back, end) = (20, 80, 100);
    let mut tracker = StreamTracker::new(r.model.clone(), r.config.clone());
    let mut log = Vec::new();
    let mut recovered = None;
    for i in 0..end {
        scene.card.hand_from_model = if (away..back).contains(&i) {
            Isometry3::translation(5000.0, 0.0, 650.0)
        } else {
            moving_card(&spec, &r, i)
        };
        let (est, _) = step(&mut tracker, &rig, &r, &scene);
        let error = (est.best.position - scene.card.hand_from_model.translation.vector).norm();
        log.push(format!("{i}: {:?} {error:.0} mm", est.state));
        let tracking = est.state == TrackState::Tracking;
        assert!(
            !(tracking && (away..back).contains(&i)),
            "frame {i}: tracking while out of view"
        );
        assert!(!tracking || error <= 20.0, "frame {i}: tracking {error:.1} mm off");
        if tracking && i >= back && recovered.is_none() {
            recovered = Some(i - back);
        }
    }
    println!("{}", log.join(", "));
    let recovered = recovered.expect("the card was tracked again");
    println!("tracking again {recovered} frames after the card came back");
    assert!(
        recovered <= 2,
        "tracking again only {recovered} frames after the card came back"
    );
}

/// The estimator's timeline on the synthetic camera at 150 mm/s: the acquisition on frame
/// 0 takes half a second to two seconds (a busy machine), so tracking resumes 24 to 120
/// frames later, up to 300 mm from the acquired pose. Whatever the gap, the acquired
/// model is relocated on the first frame after it, mostly `tracking` at once, and never
/// `tracking` when more than 20 mm off; half a second later the pose is within 5 mm and
/// the size within 5 %, `tracking`. (A
/// model that slipped onto part of the card used to stay there, 15 mm off; without the
/// relocation, a gap of a second lost the card.)
#[test]
fn tracking_recovers_the_whole_card_after_the_acquisition_gap() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let config = Config::load(None).expect("default configuration");
    let model = PhotoModel::load(&root.join("tests/data/examples/rocket.model")).expect("model");
    let mut camera =
        SyntheticSource::open(&root.join("config/scenes/rocket.toml"), &config, 60.0, 150.0).expect("scene");
    let g = camera.geometry();
    let frames: Vec<(Vec<u8>, Truth)> = (0..160)
        .map(|_| {
            let mut buf = vec![0u8; g.frame_len()];
            let info = camera.fill(&mut buf).expect("render").expect("a frame");
            (buf, info.truth[0].expect("synthetic truth"))
        })
        .collect();
    let (mut summary, mut relocated) = (Vec::new(), 0);
    let gaps = [24, 28, 32, 36, 40, 60, 90, 120];
    for gap in gaps {
        let mut tracker = StreamTracker::new(model.clone(), config.clone());
        let (mut errors, mut size_errors, mut statuses) = (Vec::new(), Vec::new(), Vec::new());
        for (i, (bytes, truth)) in frames.iter().enumerate() {
            if (1..gap).contains(&i) {
                continue;
            }
            let frame = SbsBytes {
                bytes,
                width: g.width as usize,
                height: g.height as usize,
                row_stride: g.row_stride(),
                format: g.format,
            };
            tracker.prepare(&frame).expect("HD frame");
            let est = tracker.step().expect("a prepared frame");
            let error = (est.best.position - truth.hand_from_model.translation.vector).norm();
            // Honest from the first frame after the gap: `tracking` only when right (within
            // 20 mm, the robot's tolerance in the tracking success rate).
            assert!(
                i < gap || error <= 20.0 || est.state != TrackState::Tracking,
                "gap {gap}, frame {i}: {error:.1} mm off called tracking"
            );
            if i == gap {
                relocated += usize::from(est.state == TrackState::Tracking);
                summary.push(format!("gap {gap}: relocated {error:.1} mm off, {:?}", est.state));
            }
            if i >= gap + 30 {
                errors.push(error);
                let length = est.best.size_mm(model.l_p, model.b_p)[0];
                size_errors.push((length / truth.size_mm[0] - 1.0).abs());
                statuses.push(est.state);
            }
        }
        let (error, size_error) = (Samples::new(errors).mean(), Samples::new(size_errors).mean());
        summary.push(format!("0.5 s later {error:.1} mm, size {:.1} %", 100.0 * size_error));
        assert!(
            error <= 5.0 && size_error <= 0.05,
            "tracking resumed {gap} frames after the acquisition: still {error:.1} mm and {:.1} % off after 0.5 s",
            100.0 * size_error
        );
        assert!(
            statuses.iter().all(|s| *s == TrackState::Tracking),
            "gap {gap}: {statuses:?}"
        );
    }
    println!("{}", summary.join("\n"));
    // Measured: 7 of 8 (gap 90 relocated 31 mm off, nearer and smaller, rightly
    // `searching` for 3 frames, then tracked).
    assert!(
        relocated >= 6,
        "{relocated} of {} relocations tracking at once",
        gaps.len()
    );
}

/// Every number of a pose message (frame id, capture time, generations, status, then
/// the floats as their bit patterns): equal only when bit-identical.
fn pose_bits(p: &PoseMsg) -> Vec<u64> {
    let floats = p
        .position_mm
        .iter()
        .chain(&p.orientation_wxyz)
        .chain(&p.size_mm)
        .chain([&p.fitness]);
    [p.frame_id, p.capture_time_ns, p.generations.into(), p.status.into()]
        .into_iter()
        .chain(floats.map(|v| v.to_bits()))
        .collect()
}

/// Determinism: the same rendered frames and seed through the stream tracker
/// (acquisition, then 20 tracking frames) give bit-identical pose messages; another seed
/// gives others.
#[test]
fn the_same_frames_and_seed_give_bit_identical_poses() {
    let (spec, r, rig, mut scene) = rocket_scene();
    let frames: Vec<RgbImage> = (0..21)
        .map(|i| {
            scene.card.hand_from_model = moving_card(&spec, &r, i);
            render::render(&rig, &r.config.left_from_hand, &scene)
        })
        .collect();
    let run = |seed: u64| -> Vec<Vec<u64>> {
        let mut config = r.config.clone();
        config.ga.seed = seed;
        let mut tracker = StreamTracker::new(r.model.clone(), config);
        frames
            .iter()
            .enumerate()
            .map(|(i, sbs)| {
                tracker.prepare(&sbs_frame(&rig, sbs)).expect("HD frame");
                let est = tracker.step().expect("a prepared frame");
                pose_bits(&pose_msg(tracker.model(), &est, i as u64, 1000 * i as u64))
            })
            .collect()
    };
    let seed = r.config.ga.seed;
    let first = run(seed);
    // Frame 0 acquires; the others are tracked, so both paths are compared.
    let status = |p: &Vec<u64>| p[3];
    assert!(
        first[1..].iter().all(|p| status(p) == Status::Tracking as u64),
        "{:?}",
        first.iter().map(status).collect::<Vec<_>>()
    );
    assert_eq!(first, run(seed), "the same seed and frames, another result");
    assert_ne!(first, run(seed + 1), "another seed, the same result");
}
