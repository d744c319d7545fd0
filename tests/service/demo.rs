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

/// `demo --scenario`: the take rendered, played over and over through the service, and
/// judged against its truth; its frames are removed at the end.
#[test]
fn demo_plays_a_scenario_and_judges_it_against_the_truth() {
    let _serial = serial();
    let dir = scratch("demo-scenario");
    let child = photopose()
        .args(["demo", "--scenario", "leave", "--seconds", "8", "--plot"])
        .arg(dir.join("trajectory.png"))
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("demo");
    let rendered = std::env::temp_dir().join(format!("photopose-demo-{}-leave", child.id()));
    let out = child.wait_with_output().expect("demo");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("scenario leave (6 s, looped) at 30 fps"), "{stdout}");
    // "success: S % (G of N frames with ≥ 60 % of the card in view got a tracking pose …)"
    let line = stdout
        .lines()
        .find(|l| l.starts_with("success: "))
        .unwrap_or_else(|| panic!("{stdout}"));
    let words: Vec<&str> = line.split_whitespace().collect();
    let (good, scored): (usize, usize) = (
        words[3].trim_start_matches('(').parse().unwrap(),
        words[5].parse().unwrap(),
    );
    // 8 s at 30 fps, of which the card is out of view for 1.5 s and coming back.
    assert!((120..=200).contains(&scored), "{line}");
    assert!(good > 0 && good <= scored, "{line}");
    assert!(
        stdout.contains("tracking while the card was out of view: 0"),
        "{stdout}"
    );
    assert!(!rendered.exists(), "{} left behind", rendered.display());
}
