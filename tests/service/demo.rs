//! `photopose demo`: every process of the service at once, and nothing left behind.

use std::process::Output;

use crate::common::scratch;
use crate::process::{photopose, serial};

#[test]
fn demo_runs_everything_and_leaves_no_stale_resources() {
    let _serial = serial();
    let dir = scratch("demo");
    let plot = dir.join("trajectory.png");
    let out: Output = photopose()
        .args(["demo", "--seconds", "6", "--plot"])
        .arg(&plot)
        .output()
        .expect("demo");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for needle in [
        "frames",
        "poses",
        "dropped",
        "position error",
        "p95",
        "p99",
        "trajectory plot",
    ] {
        assert!(stdout.contains(needle), "{needle:?} missing from:\n{stdout}");
    }
    let img = image::open(&plot).expect("plot PNG");
    assert_eq!((img.width(), img.height()), (1200, 900));
    // Every process has gone, and with it every photopose service.
    use iceoryx2::service::Service;
    let mut left = Vec::new();
    iceoryx2::service::ipc::Service::list(iceoryx2::config::Config::global_config(), |s| {
        left.push(s.static_details.name().as_str().to_string());
        iceoryx2::prelude::CallbackProgression::Continue
    })
    .expect("list services");
    let ours: Vec<_> = left.iter().filter(|n| n.starts_with("photopose/")).collect();
    assert!(ours.is_empty(), "services left behind: {ours:?}");
}
