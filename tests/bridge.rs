//! `photopose bridge` (feature `zenoh`) seen from ROS 2: capture, estimator and bridge
//! run as processes, and `tools/ros2_pose_client.py` (eclipse-zenoh, rosbags, iceoryx2
//! from PyPI) receives the pose sets over iceoryx2 and the bridge's ROS 2 messages over
//! Zenoh, and checks the one against the other bit for bit, the key expressions, type
//! hashes, attachments and liveliness tokens. The client listens on a free loopback port
//! and the bridge connects to it: no multicast. Without python3 and those packages the
//! tests fail under CI (`CI` set) and are skipped, loudly, elsewhere.

// Test code: a failed unwrap is a failed test.
#![allow(clippy::unwrap_used)]

#[path = "common/mod.rs"]
mod common;
#[allow(dead_code)]
#[path = "service/process.rs"]
mod process;

use std::io::Write;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use photopose::bridge::msgs::{diagnostic_status, pose_stamped, Stamp, DIAGNOSTIC_STATUS, POSE_STAMPED};
use photopose::transport::ipc::{receive_poses, Ipc};
use photopose::transport::messages::{PoseMsg, POSES_SERVICE};

use crate::common::{data, repo, scratch};
use crate::process::{estimator, model, photopose, serial, spawn, Piped, Running};

/// Whether the tests run under CI (`CI` set, and not `false` or `0`).
fn under_ci() -> bool {
    std::env::var("CI").is_ok_and(|v| !matches!(v.trim(), "" | "0" | "false"))
}

/// Why python3 cannot run the client, if it cannot.
fn python_missing() -> Option<String> {
    let probe = "import zenoh, rosbags, iceoryx2";
    match Command::new("python3")
        .args(["-c", probe])
        .stdin(Stdio::null())
        .output()
    {
        Err(e) => Some(format!("cannot run python3: {e}")),
        Ok(o) if !o.status.success() => Some(
            String::from_utf8_lossy(&o.stderr)
                .lines()
                .rfind(|l| !l.trim().is_empty())
                .unwrap_or("python3 failed")
                .to_string(),
        ),
        Ok(_) => None,
    }
}

/// True when the test may run; a loud skip (or, under CI, a failure) otherwise.
fn python_ready(test: &str) -> bool {
    let Some(why) = python_missing() else { return true };
    let help = "python3 cannot import zenoh, rosbags and iceoryx2 \
                (pip install eclipse-zenoh==1.10.2 rosbags==0.11.9 iceoryx2==0.10.0)";
    assert!(!under_ci(), "{help}; under CI this test must run: {why}");
    let _ = writeln!(std::io::stderr(), "\n######## SKIPPED {test}: {help}\n######## {why}\n");
    false
}

/// A free TCP port on the loopback interface.
fn free_port() -> u16 {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    listener.local_addr().unwrap().port()
}

/// `tools/ros2_pose_client.py` listening on `endpoint`, its output read by threads.
struct Client(Piped);

impl Client {
    fn spawn(endpoint: &str, seconds: f64) -> Self {
        let mut cmd = Command::new("python3");
        cmd.arg(repo("tools/ros2_pose_client.py"))
            .args([
                "--listen",
                endpoint,
                "--no-multicast",
                "--seconds",
                &seconds.to_string(),
            ])
            .args(["--wait", "30"])
            .current_dir(repo(""));
        Self(Piped::spawn(&mut cmd))
    }

    /// Waits for the client and returns its JSON summary, asserting it succeeded.
    fn finish(self) -> serde_json::Value {
        let (status, stdout, stderr) = self.0.finish();
        assert!(
            status.success(),
            "ros2_pose_client.py: {status}\nstderr: {stderr}\nstdout: {stdout}"
        );
        let line = stdout
            .lines()
            .rfind(|l| l.starts_with('{'))
            .unwrap_or_else(|| panic!("no summary: {stdout}"));
        serde_json::from_str(line).unwrap()
    }
}

/// `photopose bridge` connecting to `endpoint` (no multicast), its output discarded.
fn bridge(endpoint: &str) -> Running {
    spawn(&["bridge", "--connect", endpoint, "--no-multicast"])
}

/// Pose sets received over iceoryx2 in `d`, and the longest wait between two.
fn sets_in(ipc: &Ipc, sub: &photopose::transport::ipc::PoseSubscriber, d: Duration) -> (usize, Duration) {
    let start = Instant::now();
    let (mut n, mut last, mut gap) = (0, start, Duration::ZERO);
    while start.elapsed() < d {
        while receive_poses(sub).unwrap().is_some() {
            n += 1;
            gap = gap.max(last.elapsed());
            last = Instant::now();
        }
        ipc.wait(Duration::from_millis(2));
    }
    (n, gap.max(last.elapsed()))
}

/// The second card of `demo --objects 2`, its photo-model written into the scratch folder.
fn second_object() -> (String, String) {
    let out = scratch("bridge").join("hopper.model");
    let status = photopose()
        .args(["model", "--photo"])
        .arg(data("photos/hopper.jpg"))
        .args(["--box", "100,20,340,480", "--output"])
        .arg(&out)
        .status()
        .unwrap();
    assert!(status.success(), "photopose model failed");
    let scene = repo("config/scenes/hopper-beside.toml").display().to_string();
    (format!("hopper={}", out.display()), scene)
}

#[test]
fn a_ros2_subscriber_receives_every_pose_bit_for_bit() {
    let _serial = serial();
    if !python_ready("a_ros2_subscriber_receives_every_pose_bit_for_bit") {
        return;
    }
    // Two objects, so that each gets its own topics when it first appears.
    let (hopper, second_card) = second_object();
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let client = Client::spawn(&endpoint, 10.0);
    let _bridge = bridge(&endpoint);
    let rocket = format!("rocket={}", model());
    let _estimator = spawn(&["estimator", "--model", &rocket, "--model", &hopper]);
    let first = format!("synthetic:{}", repo("config/scenes/pair.toml").display());
    let _capture = spawn(&["capture", "--source", &first, "--card", &second_card]);
    let summary = client.finish();
    println!("ros2_pose_client.py: {summary}");
    let share = summary["share"].as_f64().unwrap();
    assert!(share >= 0.95, "{summary}");
    assert_eq!(summary["bit_equal"], true, "{summary}");
    assert_eq!(summary["liveliness"]["ok"], true, "{summary}");
    assert!(summary["status_messages_checked"].as_u64().unwrap() > 0, "{summary}");
    assert_eq!(summary["objects"], serde_json::json!(["hopper", "rocket"]), "{summary}");
    assert_eq!(summary["liveliness"]["publisher_tokens"], 4, "{summary}");
    println!(
        "bridge: {} of {} poses over Zenoh ({:.1} %), bit-equal; added latency p50 {:.2} ms, p99 {:.2} ms",
        summary["paired"],
        summary["ipc_poses"],
        100.0 * share,
        summary["latency_ms"]["p50"].as_f64().unwrap(),
        summary["latency_ms"]["p99"].as_f64().unwrap(),
    );
}

#[test]
fn the_bridge_reconnects_and_never_holds_the_estimator_up() {
    let _serial = serial();
    if !python_ready("the_bridge_reconnects_and_never_holds_the_estimator_up") {
        return;
    }
    let ipc = Ipc::new("photopose-test-bridge").unwrap();
    let sub = ipc.pose_subscriber(POSES_SERVICE).unwrap();
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let _estimator = estimator();
    let _capture = spawn(&["capture", "--source", "synthetic"]);
    let bridge = bridge(&endpoint);
    // The Zenoh side comes, dies without a goodbye, and comes back on the same port.
    let first = Client::spawn(&endpoint, 60.0);
    std::thread::sleep(Duration::from_secs(8));
    drop(first);
    std::thread::sleep(Duration::from_secs(3));
    let restarted = Instant::now();
    let second = Client::spawn(&endpoint, 4.0).finish();
    println!("after the Zenoh peer's restart: {second}");
    assert!(second["share"].as_f64().unwrap() >= 0.95, "{second}");
    assert_eq!(second["bit_equal"], true, "{second}");
    let waited = second["waited_s"].as_f64().unwrap();
    println!(
        "poses flowed again {waited:.2} s after the Zenoh peer restarted ({:?} in all)",
        restarted.elapsed()
    );

    // The bridge dies: the estimator goes on publishing (its rate varies with what the
    // GA does, so half of the rate before is plenty), without a pause.
    while receive_poses(&sub).unwrap().is_some() {} // the sets queued while the clients ran
    let (before, _) = sets_in(&ipc, &sub, Duration::from_secs(3));
    drop(bridge);
    let (after, gap) = sets_in(&ipc, &sub, Duration::from_secs(3));
    println!(
        "pose sets in 3 s over iceoryx2: {before} with the bridge, {after} after it was killed \
         (longest gap {gap:?})"
    );
    assert!(before > 0 && 2 * after >= before, "{before} sets before, {after} after");
    assert!(
        gap < Duration::from_millis(500),
        "no pose for {gap:?} after the bridge was killed"
    );
}

/// Checks the Rust CDR bytes and type hashes against rosbags' (run by `python3 -c`).
const ROSBAGS_CHECK: &str = r#"
import json, sys
from rosbags.typesys import Stores, get_typestore
ts = get_typestore(Stores.ROS2_JAZZY)
T = ts.types
case = json.loads(sys.argv[1])
stamp = T["builtin_interfaces/msg/Time"](sec=case["sec"], nanosec=case["nanosec"])
header = T["std_msgs/msg/Header"](stamp=stamp, frame_id=case["frame_id"])
x, y, z = (float(v) for v in case["position_m"])
qx, qy, qz, qw = (float(v) for v in case["orientation_xyzw"])
pose = T["geometry_msgs/msg/Pose"](
    position=T["geometry_msgs/msg/Point"](x=x, y=y, z=z),
    orientation=T["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=qz, w=qw),
)
msg = T["geometry_msgs/msg/PoseStamped"](header=header, pose=pose)
kv = T["diagnostic_msgs/msg/KeyValue"]
status = T["diagnostic_msgs/msg/DiagnosticStatus"](
    level=case["level"], name=case["name"], message=case["message"],
    hardware_id=case["hardware_id"], values=[kv(key=k, value=v) for k, v in case["values"]],
)
print(json.dumps({
    "pose": ts.serialize_cdr(msg, "geometry_msgs/msg/PoseStamped").hex(),
    "status": ts.serialize_cdr(status, "diagnostic_msgs/msg/DiagnosticStatus").hex(),
    "pose_hash": ts.hash_rihs01("geometry_msgs/msg/PoseStamped"),
    "status_hash": ts.hash_rihs01("diagnostic_msgs/msg/DiagnosticStatus"),
}))
"#;

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

#[test]
fn the_messages_are_the_bytes_rosbags_writes() {
    if !python_ready("the_messages_are_the_bytes_rosbags_writes") {
        return;
    }
    let pose = PoseMsg {
        frame_id: 1234,
        capture_time_ns: 5,
        position_mm: [0.1, -1.0 / 3.0, 650.0 + 1e-9],
        orientation_wxyz: [0.9, 0.1, -0.3, 1.0 / 3.0],
        size_mm: [180.0 / 7.0, 22.5],
        fitness: 2.0 / 3.0,
        generations: 41,
        status: 1,
        ..PoseMsg::default()
    };
    let stamp = Stamp::from_ns(1_764_000_000_987_654_321);
    let (mut pose_bytes, mut status_bytes) = (Vec::new(), Vec::new());
    pose_stamped(&mut pose_bytes, stamp, "hand", &pose);
    diagnostic_status(&mut status_bytes, "rocket", &pose);
    let [w, x, y, z] = pose.orientation_wxyz;
    // Shortest round-trip forms: Python parses them to the same doubles.
    let position_m = pose.position_mm.map(|v| format!("{:?}", v / 1000.0));
    let orientation_xyzw = [x, y, z, w].map(|v| format!("{v:?}"));
    let case = serde_json::json!({
        "sec": stamp.sec, "nanosec": stamp.nanosec, "frame_id": "hand",
        "position_m": position_m,
        "orientation_xyzw": orientation_xyzw,
        "level": 1, "name": "rocket", "message": "searching", "hardware_id": "photopose",
        "values": [
            ["fitness", (2.0f64 / 3.0).to_string()], ["generations", "41"], ["frame_id", "1234"],
            ["size_x_m", (180.0f64 / 7.0 / 1000.0).to_string()], ["size_y_m", "0.0225"],
        ],
    });
    let out = Command::new("python3")
        .args(["-c", ROSBAGS_CHECK, &case.to_string()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let got: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(got["pose"], hex(&pose_bytes), "PoseStamped");
    assert_eq!(got["status"], hex(&status_bytes), "DiagnosticStatus");
    assert_eq!(got["pose_hash"], POSE_STAMPED.hash);
    assert_eq!(got["status_hash"], DIAGNOSTIC_STATUS.hash);
}

/// One `error:` line and a failure status for each bad argument, no panic.
#[test]
fn bad_arguments_are_one_clear_line() {
    let cases: [(&[&str], &str); 4] = [
        (&["--connect", "localhost:7447"], "bad endpoint"),
        (&["--connect", "udp/127.0.0.1:7447"], "only tcp is built in"),
        (&["--frame-id", "/hand"], "bad frame id"),
        (&["--domain", "300"], "bad domain id"),
    ];
    for (args, want) in cases {
        let out = photopose()
            .arg("bridge")
            .args(args)
            .stdin(Stdio::null())
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} succeeded");
        let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
        assert_eq!(lines.len(), 1, "{args:?}: {stderr}");
        assert!(
            lines[0].starts_with("error: ") && lines[0].contains(want),
            "{args:?}: {stderr}"
        );
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
    }
}
