//! The ZED source without a camera: a scripted device feeds the real streaming and
//! reconnect logic, its frames are recorded, replayed and tracked as YUYV; and the
//! command line fails fast and clearly without a camera.

use std::sync::Arc;
use std::time::{Duration, Instant};

use nalgebra::{Isometry3, Translation3};
use photopose::camera::calibration::Resolution;
use photopose::capture::record::Recorder;
use photopose::capture::replay::ReplaySource;
use photopose::capture::sequence::Sequence;
use photopose::capture::zed::fake::{Attempt, ScriptedOpener, Step};
use photopose::capture::zed::stream::{Backoff, ZedSource};
use photopose::capture::zed::Mode;
use photopose::capture::FrameSource;
use photopose::config::Config;
use photopose::estimator::model::PhotoModel;
use photopose::estimator::tracking::StreamTracker;
use photopose::render::{Renderer, SceneSpec};
use photopose::vision::lookup::SbsBytes;
use photopose::vision::PixelFormat;

use crate::cli::{fails_with, photopose};
use crate::common::{data, repo, scratch};
use photopose::vision::color::yuyv_from_rgb;

/// Frames of the rocket card moving 2–3 mm per frame, rendered in HD and encoded as the
/// ZED sends them (YUYV), with the card's true poses.
fn yuyv_frames(config: &Config, n: usize) -> (Vec<Arc<[u8]>>, Vec<Isometry3<f64>>) {
    let spec = SceneSpec::load(&repo("config/scenes/rocket.toml")).expect("scene");
    let mut scene = spec.build(&config.left_from_hand).expect("scene");
    let rig = config.calibration.rig(Resolution::HD).expect("HD");
    let mut renderer = Renderer::new(&rig, &config.left_from_hand, &scene);
    let start = scene.card.hand_from_model;
    let w = rig.width as usize;
    let mut rgb = vec![0u8; renderer.frame_len()];
    let (mut frames, mut truth) = (Vec::new(), Vec::new());
    for i in 0..n {
        let pose = Translation3::new(2.0 * i as f64, -(i as f64), 0.5 * i as f64) * start;
        scene.card.hand_from_model = pose;
        renderer.render_into(&scene, &mut rgb);
        frames.push(Arc::from(yuyv_from_rgb(&rgb, w)));
        truth.push(pose);
    }
    (frames, truth)
}

#[test]
fn scripted_camera_frames_are_recorded_replayed_and_tracked_as_yuyv() {
    let config = Config::load(None).expect("config");
    let (frames, truth) = yuyv_frames(&config, 8);
    let stamp = |i: usize| 1_000_000_000 + i as u64 * 16_666_667;
    let step = |i: usize| Step::frame(frames[i].clone(), stamp(i));
    // The camera delivers three frames and a short buffer, is unplugged, is missing
    // twice, then comes back with the rest.
    let opener = ScriptedOpener::new([
        Attempt::Opens(vec![
            step(0),
            step(1),
            step(2),
            Step::Short(4096),
            step(3),
            Step::Unplug,
        ]),
        Attempt::Missing,
        Attempt::Missing,
        Attempt::Opens((4..8).map(step).collect()),
    ]);
    let backoff = Backoff {
        first: Duration::from_millis(1),
        max: Duration::from_millis(4),
        stall: Duration::from_secs(5),
    };
    let mut camera = ZedSource::open(opener, Mode::new(Resolution::HD, 60), backoff).expect("fake camera");
    let geometry = camera.geometry();
    assert_eq!(geometry.format, PixelFormat::Yuyv);
    let dir = scratch("zed-record");
    let mut recorder = Recorder::create(&dir, geometry, "zed").expect("recorder");
    let mut buf = vec![0u8; geometry.frame_len()];
    let mut id = 0;
    for _ in 0..200 {
        let due = camera.next_due().expect("a camera never ends");
        std::thread::sleep(due.saturating_duration_since(Instant::now()));
        if let Some(info) = camera.fill(&mut buf).expect("fill") {
            assert!(buf == *frames[id as usize], "frame {id} changed on the way");
            recorder.record(id, &info, &buf).expect("record");
            id += 1;
        }
        if id == 8 {
            break;
        }
    }
    let s = camera.stats;
    assert_eq!(
        (id, s.short, s.lost, s.failed_opens, s.reconnects),
        (8, 1, 1, 2, 1),
        "{s:?}"
    );
    assert_eq!(recorder.skipped, 0);
    assert_eq!(recorder.finish().expect("recording"), 8);

    // The recording holds the frames with the camera's timestamps, as `.yuyv` files.
    let seq = Sequence::open(&dir).expect("sequence");
    assert_eq!(seq.info.pixel_format, "YUYV");
    assert_eq!(seq.times(), (0..8).map(stamp).collect::<Vec<_>>());
    assert!(seq
        .frames
        .iter()
        .all(|f| f.file.ends_with(".yuyv") && f.truth.is_none()));

    // Replayed as YUYV and tracked straight from the YUYV bytes.
    let mut replay = ReplaySource::open(&dir, Some(1000.0), false).expect("replay");
    assert_eq!(replay.geometry(), geometry);
    let model = PhotoModel::load(&data("examples/rocket.model")).expect("model");
    let mut tracker = StreamTracker::new(model, config.clone());
    let mut errors = Vec::new();
    for (i, pose) in truth.iter().enumerate() {
        replay.next_due().expect("8 frames");
        replay.fill(&mut buf).expect("replayed frame").expect("a frame");
        assert!(buf == *frames[i], "replayed frame {i} differs");
        let frame = SbsBytes {
            bytes: &buf,
            width: geometry.width as usize,
            height: geometry.height as usize,
            row_stride: geometry.row_stride(),
            format: PixelFormat::Yuyv,
        };
        tracker.prepare(&frame).expect("YUYV frame");
        let est = tracker.step().expect("estimate");
        errors.push((est.best.position - pose.translation.vector).norm());
    }
    assert!(replay.next_due().is_none(), "the replay ends after 8 frames");
    println!("position error per YUYV frame (mm): {errors:.1?}");
    // Frame 0 is the acquisition, which may end at a quick pass the verdict does not
    // find (measured 19.1 mm off, `searching`); the frames after it are tracked.
    assert!(errors[0] < 25.0, "{errors:?}");
    assert!(errors[1..].iter().all(|&e| e < 10.0), "{errors:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[cfg(feature = "zed")]
#[test]
fn zed_capture_without_a_camera_fails_fast_with_one_line() {
    let start = Instant::now();
    let out = photopose(&["capture", "--source", "zed", "--device", "/dev/video99"]);
    let took = start.elapsed();
    println!("--device /dev/video99 failed in {:.0} ms", took.as_secs_f64() * 1e3);
    fails_with(&out, &["cannot open /dev/video99", "No such file or directory"]);
    assert_eq!(
        String::from_utf8_lossy(&out.stderr),
        "error: cannot open /dev/video99: No such file or directory (os error 2)\n"
    );
    assert!(took < Duration::from_secs(1), "took {took:?}");
    let out = photopose(&["capture", "--source", "zed", "--resolution", "2K", "--fps", "30"]);
    fails_with(
        &out,
        &["no 2K mode at 30 fps; valid modes: 2K@15, FHD@15/30, HD@15/30/60, VGA@15/30/60/100"],
    );
}

#[cfg(not(feature = "zed"))]
#[test]
fn zed_capture_says_to_rebuild_with_the_feature() {
    let out = photopose(&["capture", "--source", "zed", "--device", "/dev/video99"]);
    fails_with(&out, &["--source zed", "--features zed"]);
}

#[test]
fn zed_options_belong_to_the_zed_source() {
    let out = photopose(&["capture", "--source", "synthetic", "--resolution", "HD"]);
    fails_with(&out, &["--resolution and --device apply to --source zed only"]);
}
