//! `photopose viewer` (feature `rerun`) records what the service publishes: a short
//! synthetic run of capture, estimator and viewer, the poses collected here as any
//! client would, then `tools/check_rrd.py` opens the `.rrd` with the Python rerun-sdk of
//! the same version and checks entities, time lines and numbers against those poses.
//! Without python3 and rerun-sdk the test fails under CI (`CI` set) and is skipped,
//! loudly, elsewhere.

// Test code: a failed unwrap is a failed test.
#![allow(clippy::unwrap_used)]

#[path = "common/mod.rs"]
mod common;
#[allow(dead_code)]
#[path = "service/process.rs"]
mod process;

use std::io::Write;
use std::process::Command;
use std::time::Duration;

use photopose::transport::messages::PoseMsg;

use crate::common::{repo, scratch};
use crate::process::{estimator, model, serial, spawn, Watcher};

/// The rerun-sdk version of the Rust SDK in Cargo.toml.
const RERUN_SDK: &str = "0.36.3";

/// Whether the tests run under CI (`CI` set, and not `false` or `0`).
fn under_ci() -> bool {
    std::env::var("CI").is_ok_and(|v| !matches!(v.trim(), "" | "0" | "false"))
}

/// Why python3 cannot read recordings of this version, if it cannot.
fn python_rerun_missing() -> Option<String> {
    let probe = "import rerun, sys; sys.exit(0 if rerun.__version__ == sys.argv[1] else 3)";
    match Command::new("python3").args(["-c", probe, RERUN_SDK]).output() {
        Err(e) => Some(format!("cannot run python3: {e}")),
        Ok(o) if o.status.code() == Some(3) => Some(format!("rerun-sdk is not version {RERUN_SDK}")),
        Ok(o) if !o.status.success() => Some(String::from_utf8_lossy(&o.stderr).trim().to_string()),
        Ok(_) => None,
    }
}

/// A pose as JSON for the checker (serde_json writes floats that Python reads back
/// exactly).
fn json(p: &PoseMsg) -> serde_json::Value {
    serde_json::json!({
        "frame_id": p.frame_id,
        "capture_time_ns": p.capture_time_ns,
        "position_mm": p.position_mm,
        "fitness": p.fitness,
        "status": p.status,
    })
}

#[test]
fn the_recording_holds_the_published_poses() {
    let _serial = serial();
    if let Some(why) = python_rerun_missing() {
        let help = format!("python3 cannot import rerun-sdk {RERUN_SDK} (pip install rerun-sdk=={RERUN_SDK})");
        assert!(!under_ci(), "{help}; under CI this test must run: {why}");
        let _ = writeln!(
            std::io::stderr(),
            "\n######## SKIPPED the_recording_holds_the_published_poses: {help}\n######## {why}\n"
        );
        return;
    }
    let dir = scratch("viewer");
    let rrd = dir.join("run.rrd");
    let mut watch = Watcher::new("photopose-test-viewer");
    let rrd_arg = rrd.display().to_string();
    let viewer = spawn(&["viewer", "--save", &rrd_arg, "--model", &model(), "--seconds", "60"]);
    let estimator = estimator();
    let capture = spawn(&["capture", "--source", "synthetic", "--seconds", "60"]);
    watch.collect(Duration::from_secs(10));
    capture.terminate();
    watch.collect(Duration::from_millis(300));
    estimator.terminate();
    viewer.terminate();
    watch.drain();
    let poses: Vec<_> = watch.got.iter().map(|(p, _)| json(p)).collect();
    let truths: Vec<_> = watch.truths.values().map(json).collect();
    println!("collected {} poses and {} truths", poses.len(), truths.len());
    assert!(poses.len() >= 20, "only {} poses in 10 s", poses.len());
    let published = dir.join("poses.json");
    let text = serde_json::json!({ "poses": poses, "truths": truths }).to_string();
    std::fs::write(&published, text).unwrap();
    let out = Command::new("python3")
        .arg(repo("tools/check_rrd.py"))
        .args([&rrd, &published])
        .output()
        .expect("python3");
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    println!("{stdout}");
    assert!(out.status.success(), "check_rrd.py: {}\n{stderr}{stdout}", out.status);
    let _ = std::fs::remove_dir_all(&dir);
}
