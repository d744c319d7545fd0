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

/// `demo --scenario NAME --once`: the take rendered, played once through the service as
/// a recorded sequence is, and judged against its truth; the demo stops when the take
/// ends, and its frames are removed.
#[test]
fn demo_plays_a_scenario_once_and_judges_it_against_the_truth() {
    let _serial = serial();
    let dir = scratch("demo-scenario");
    let child = photopose()
        .args(["demo", "--scenario", "leave", "--once", "--seconds", "30", "--plot"])
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
    assert!(stdout.contains("scenario leave (6 s, once) at 30 fps"), "{stdout}");
    // The take's 180 frames, each once ("frames 180  poses 180 (…"): the replay did not
    // loop, and the demo stopped at its end with (nearly) every frame's pose.
    let counts: Vec<usize> = stdout
        .lines()
        .find(|l| l.starts_with("frames "))
        .map(|l| l.split_whitespace().take(4).filter_map(|w| w.parse().ok()).collect())
        .unwrap_or_default();
    assert!(counts.len() == 2 && counts[0] == 180 && counts[1] >= 170, "{stdout}");
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
    // The card is out of view for 1.5 s and coming back for a while: 129 of the 180
    // frames show at least 60 % of it.
    assert_eq!(scored, 129, "{line}");
    assert!(good > 0 && good <= scored, "{line}");
    assert!(
        stdout.contains("tracking while the card was out of view: 0"),
        "{stdout}"
    );
    // Found again after it came back ("back in view → good tracking pose after: 1.00 s
    // (0.53 s after both eyes see it)"): the right eye sees the card coming in at the
    // left edge about 0.45 s after the left eye.
    let back = stdout
        .lines()
        .find_map(|l| l.strip_prefix("back in view → good tracking pose after: "))
        .unwrap_or_else(|| panic!("{stdout}"));
    let seconds: Vec<f64> = (back.split(['(', ' '])).filter_map(|w| w.parse().ok()).collect();
    assert!(seconds.len() == 2, "the left eye's and both eyes' times: {back}");
    assert!(seconds[0] < 2.5, "not found again within 2.5 s: {back}");
    assert!(
        (0.3..0.6).contains(&(seconds[0] - seconds[1])),
        "both eyes see it 0.3-0.6 s after the left one: {back}"
    );
    assert!(!rendered.exists(), "{} left behind", rendered.display());
}
