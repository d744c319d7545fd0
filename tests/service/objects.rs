//! Several objects at once: two cards on the synthetic camera, each tracked by its own
//! population in one estimator and published together in one pose set per frame; and
//! the versioned contract: a client built for the single-pose layout of version 1 is
//! refused with a type error instead of misreading a version-2 set.

use std::time::Duration;

use iceoryx2::prelude::*;
use photopose::cli::report::stats::Samples;
use photopose::transport::ipc::Ipc;
use photopose::transport::messages::{PoseMsg, Status, POSES_SERVICE};

use crate::common::{data, repo, scratch};
use crate::process::{model, photopose, position_error, serial, spawn, Watcher};

/// The scenes of `demo --objects 2`: the first card and the wall, the second card and
/// its photo's box.
const PAIR_SCENE: &str = "config/scenes/pair.toml";
const SECOND_SCENE: &str = "config/scenes/hopper-beside.toml";
const SECOND_BOX: &str = "100,20,340,480";

/// The photo-model of the second card, written into the test's scratch folder.
fn second_model() -> String {
    let out = scratch("objects").join("hopper.model");
    let status = photopose()
        .args(["model", "--photo"])
        .arg(data("photos/hopper.jpg"))
        .args(["--box", SECOND_BOX, "--output"])
        .arg(&out)
        .status()
        .expect("photopose model");
    assert!(status.success(), "photopose model failed");
    out.display().to_string()
}

#[test]
fn two_objects_are_tracked_together_each_against_its_own_truth() {
    let _serial = serial();
    let mut w = Watcher::new("photopose-test-objects");
    let (rocket, hopper) = (format!("rocket={}", model()), format!("hopper={}", second_model()));
    let _estimator = spawn(&["estimator", "--model", &rocket, "--model", &hopper]);
    let first = format!("synthetic:{}", repo(PAIR_SCENE).display());
    let second = repo(SECOND_SCENE).display().to_string();
    let _capture = spawn(&["capture", "--source", &first, "--speed", "150", "--card", &second]);
    w.collect(Duration::from_secs(30));
    assert!(w.sets.len() > 600, "only {} pose sets", w.sets.len());
    for set in &w.sets {
        let names: Vec<&str> = set.objects().iter().map(|o| o.name()).collect();
        assert_eq!(names, ["rocket", "hopper"], "every set carries both, in --model order");
        let [a, b] = [0, 1].map(|k| set.objects()[k].pose);
        assert_eq!((a.frame_id, a.capture_time_ns), (b.frame_id, b.capture_time_ns));
    }
    // Share of each object's poses after its acquisition that are `tracking`. The hopper
    // card is acquired and relocated in the background while the rocket is tracked; a
    // relocation the verdict doubts can leave it `searching` for a while (96–100 %
    // measured), so its floor is lower.
    //
    // The hopper painting's large even areas pin its depth weakly while it is tracked:
    // now and then its estimate slides along the line of sight by up to ~20 mm over a
    // few frames before a whole-frame step puts it back (p95 7.3–10.7 mm over runs, the
    // median 1.9–2.6 mm), so its p95 bound is 15 mm; the rocket card's p95 is 2.6–3.1 mm.
    for (name, floor, p95) in [("rocket", 0.95, 10.0), ("hopper", 0.85, 15.0)] {
        let poses: Vec<PoseMsg> = w.sets.iter().filter_map(|s| s.get(name).copied()).collect();
        // After the object's own acquisition (its first tracking pose).
        let start = poses
            .iter()
            .position(|p| p.status == Status::Tracking as u32)
            .unwrap_or_else(|| panic!("{name} was never tracked"));
        let tracked = &poses[start + 1..];
        let tracking: Vec<&PoseMsg> = tracked.iter().filter(|p| p.status == Status::Tracking as u32).collect();
        let errors = Samples::new(tracking.iter().map(|p| {
            let truth = w.truth_sets[&p.frame_id].get(name).expect("truth of each card");
            position_error(p, truth)
        }));
        println!(
            "{name}: acquired at pose {start}, then {} poses, {} tracking, error median {:.1} mm p95 {:.1} mm",
            tracked.len(),
            tracking.len(),
            errors.median(),
            errors.percentile(95.0)
        );
        assert!(errors.median() <= 4.0, "{name}: median {:.1} mm", errors.median());
        assert!(
            errors.percentile(95.0) <= p95,
            "{name}: p95 {:.1} mm",
            errors.percentile(95.0)
        );
        let share = tracking.len() as f64 / tracked.len() as f64;
        assert!(share >= floor, "{name}: {:.0} % tracking", 100.0 * share);
    }
}

/// The version-1 pose, declared by a client that was never rebuilt.
#[repr(C)]
#[derive(Debug, Default, Clone, Copy, ZeroCopySend)]
#[type_name("PhotoposePose")]
struct OldPose([u64; 14]);

#[test]
fn a_version_1_client_gets_a_type_error() {
    let _serial = serial();
    let ipc = Ipc::new("photopose-test-contract").expect("iceoryx2 node");
    let _publisher = ipc.pose_publisher(POSES_SERVICE).expect("version 2 publisher");
    let node = NodeBuilder::new().create::<ipc::Service>().expect("node");
    let name = ServiceName::new(POSES_SERVICE).expect("name");
    let old = node.service_builder(&name).publish_subscribe::<OldPose>().open();
    let Err(error) = old else {
        panic!("a version-1 client must not open the service")
    };
    let error = format!("{error:?}");
    assert!(error.contains("IncompatibleTypes"), "{error}");
}
