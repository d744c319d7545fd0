//! The real-time service as separate processes: `photopose capture` (synthetic camera,
//! moving card) and `photopose estimator` publish over iceoryx2; this test subscribes
//! to `photopose/poses` and `photopose/truth` like any client would.

use std::collections::HashMap;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use photopose::ipc::Ipc;
use photopose::messages::{status, PoseMsg, POSES_SERVICE, TRUTH_SERVICE};

/// Kills a child process when dropped (a failed assertion must not leave it running).
struct Running(Child);

impl Drop for Running {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn spawn(args: &[&str]) -> Running {
    let child = Command::new(env!("CARGO_BIN_EXE_photopose"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("photopose binary");
    Running(child)
}

#[test]
fn capture_and_estimator_processes_track_a_moving_card() {
    let model = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/examples/rocket.model");
    let ipc = Ipc::new("photopose-test-client").expect("iceoryx2 node");
    let poses = ipc.pose_subscriber(POSES_SERVICE).expect("poses");
    let truth = ipc.pose_subscriber(TRUTH_SERVICE).expect("truth");
    // The estimator first: processes may start in any order.
    let _estimator = spawn(&["estimator", "--model", model.to_str().unwrap(), "--seconds", "9"]);
    std::thread::sleep(Duration::from_millis(300));
    let _capture = spawn(&["capture", "--speed", "150", "--seconds", "8"]);

    let mut got: Vec<PoseMsg> = Vec::new();
    let mut truths: HashMap<u64, PoseMsg> = HashMap::new();
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(9) {
        while let Some(s) = poses.receive().expect("receive pose") {
            got.push(*s.payload());
        }
        while let Some(s) = truth.receive().expect("receive truth") {
            truths.insert(s.payload().frame_id, *s.payload());
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    assert!(got.len() > 100, "only {} poses", got.len());
    // Every pose belongs to a real frame, in order, once, with consistent timestamps.
    for pair in got.windows(2) {
        assert!(
            pair[1].frame_id > pair[0].frame_id,
            "frame ids {} then {}",
            pair[0].frame_id,
            pair[1].frame_id
        );
    }
    for p in &got {
        let t = truths
            .get(&p.frame_id)
            .unwrap_or_else(|| panic!("pose for unknown frame {}", p.frame_id));
        assert_eq!(p.capture_time_ns, t.capture_time_ns, "frame {}", p.frame_id);
        assert!(p.publish_time_ns > p.capture_time_ns);
    }
    // Cold start: the first pose is the acquisition.
    let first = &got[0];
    let acquisition_s = (first.publish_time_ns - first.capture_time_ns) as f64 * 1e-9;
    // Tracking error against the truth of the same frame, after acquisition.
    let mut errors: Vec<f64> = got[1..]
        .iter()
        .map(|p| {
            let t = &truths[&p.frame_id];
            (0..3)
                .map(|i| (p.position_mm[i] - t.position_mm[i]).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .collect();
    errors.sort_by(f64::total_cmp);
    let p95 = errors[(errors.len() as f64 * 0.95).ceil() as usize - 1];
    let tracking = got.iter().filter(|p| p.status == status::TRACKING).count();
    let mut latency: Vec<f64> = got[1..]
        .iter()
        .map(|p| (p.publish_time_ns - p.capture_time_ns) as f64 * 1e-6)
        .collect();
    latency.sort_by(f64::total_cmp);
    println!(
        "{} poses ({tracking} tracking), acquisition {acquisition_s:.2} s, error median {:.1} mm p95 {p95:.1} mm, \
         capture→pose p50 {:.1} ms p99 {:.1} ms",
        got.len(),
        errors[errors.len() / 2],
        latency[latency.len() / 2],
        latency[(latency.len() as f64 * 0.99).ceil() as usize - 1]
    );
    assert!(p95 <= 10.0, "p95 tracking error {p95:.1} mm at 150 mm/s");
    assert!(acquisition_s < 1.0, "acquisition took {acquisition_s:.2} s");
    assert!(
        tracking as f64 >= 0.95 * got.len() as f64,
        "{tracking} of {} poses tracking",
        got.len()
    );
}
