//! `photopose latency`: the running pipeline's timings, and the two transports compared.

use std::time::Duration;

use crate::process::{estimator, photopose, serial, spawn, Watcher};

/// `photopose latency --json` (or `--compare-transport`) as parsed JSON.
fn latency_json(extra: &[&str]) -> serde_json::Value {
    let out = photopose()
        .args(["latency", "--json"])
        .args(extra)
        .output()
        .expect("photopose binary");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).unwrap();
    assert_eq!(text.lines().count(), 1, "one JSON object: {text}");
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{e}: {text}"))
}

#[test]
fn latency_measures_the_running_pipeline() {
    let _serial = serial();
    let _estimator = estimator();
    let _capture = spawn(&["capture"]);
    let mut w = Watcher::new("photopose-test-latency");
    assert!(w.until_tracking(Duration::from_secs(12)), "no tracking pose");
    let r = latency_json(&["--seconds", "3"]);
    println!("latency: {r}");
    let n = |k: &str| r[k].as_f64().unwrap_or_else(|| panic!("no number {k} in {r}"));
    // 3 s of a 60 fps camera, a pose for nearly every frame that no (re)acquisition
    // skipped (one may still happen in the window when the track is lost). A busy machine
    // may render fewer; a camera that fell behind while the acquisition took both cores
    // sends the frames it owes back to back, so up to a second's worth more can arrive.
    assert!((120.0..=240.0).contains(&n("frames")), "{} frames", n("frames"));
    let tracked = n("frames") - n("skipped_while_acquiring");
    assert!(n("poses") >= 0.9 * tracked, "{} poses for {tracked} frames", n("poses"));
    assert!(
        n("dropped_frames") <= 0.05 * n("frames"),
        "{} dropped",
        n("dropped_frames")
    );
    for (p50, p99) in [
        ("transport_p50_us", "transport_p99_us"),
        ("estimation_p50_ms", "estimation_p99_ms"),
        ("end_to_end_p50_ms", "end_to_end_p99_ms"),
    ] {
        assert!(n(p50) > 0.0 && n(p50) <= n(p99), "{p50} {} {p99} {}", n(p50), n(p99));
    }
    assert!(n("end_to_end_max_ms") >= n("end_to_end_p99_ms"));
    // A pose is received after it is published: end to end includes estimation.
    assert!(n("end_to_end_p50_ms") >= n("estimation_p50_ms"));
    // Frames travel by reference: far below a millisecond.
    assert!(
        n("transport_p50_us") < 1000.0,
        "transport p50 {} µs",
        n("transport_p50_us")
    );
}

/// The one stderr line of a `photopose latency` run that failed.
fn latency_error(seconds: &str) -> String {
    let out = photopose()
        .args(["latency", "--seconds", seconds])
        .output()
        .expect("photopose binary");
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        out.stdout.is_empty(),
        "no report expected: {}",
        String::from_utf8_lossy(&out.stdout)
    );
    assert_eq!(err.trim_end().lines().count(), 1, "one line expected: {err}");
    err.trim_end().to_string()
}

/// Nothing to measure is an error that names the missing process, not a report of
/// undefined figures (it printed NaN for every percentile and exited 0).
#[test]
fn latency_without_a_pipeline_names_the_missing_process() {
    let _serial = serial();
    assert_eq!(
        latency_error("0.5"),
        "error: no frames and no poses in 0.5 s: start `photopose capture` and `photopose estimator` first"
    );
    let _capture = spawn(&["capture"]);
    std::thread::sleep(Duration::from_secs(1));
    let err = latency_error("1.5");
    let frames: usize = err
        .strip_prefix("error: ")
        .and_then(|e| e.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("a frame count first: {err}"));
    assert!(frames > 30, "{err}");
    assert!(
        err.ends_with(" frames but no poses in 1.5 s: is `photopose estimator` running?"),
        "{err}"
    );
}

#[test]
fn compare_transport_times_both_transports_on_the_same_frames() {
    let _serial = serial();
    let r = latency_json(&["--compare-transport", "--seconds", "1"]);
    println!("compare transport: {r}");
    assert_eq!(r["frames"], 60);
    assert_eq!(r["frame_bytes"], 2 * 1280 * 720 * 3);
    let p50 = |t: &str| r[t]["p50"].as_f64().unwrap_or_else(|| panic!("no {t}.p50 in {r}"));
    let ratio = r["ratio_p50"].as_f64().unwrap();
    assert!((ratio - p50("unix_socket_us") / p50("iceoryx2_us")).abs() < 1e-9 * ratio);
    for t in ["iceoryx2_us", "unix_socket_us"] {
        assert!(p50(t) > 0.0 && r[t]["max"].as_f64().unwrap() >= p50(t));
    }
    // Copying 5.5 MB cannot beat passing a reference.
    assert!(ratio > 1.0, "ratio {ratio}");
}
