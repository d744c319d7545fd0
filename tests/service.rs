//! The real-time service as separate processes: `photopose capture`, `estimator`,
//! `controller` and `demo` talk over iceoryx2; these tests subscribe to
//! `photopose/poses` and `photopose/truth` like any client would, in Rust and through
//! the Python client `tools/pose_client.py`. They share the service names, so they run
//! one at a time ([`serial`]).

mod common;

use std::collections::HashMap;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::sync::{Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use common::scratch;
use photopose::cli::report::stats::Samples;
use photopose::client::PoseClient;
use photopose::transport::ipc::{send_pose, Ipc, PoseSubscriber};
use photopose::transport::messages::{monotonic_ns, PoseMsg, Status, POSES_SERVICE, TRUTH_SERVICE};

/// One process test at a time (they use the same iceoryx2 services).
fn serial() -> MutexGuard<'static, ()> {
    static LOCK: Mutex<()> = Mutex::new(());
    LOCK.lock().unwrap_or_else(|e| e.into_inner())
}

/// Kills a child process when dropped (a failed assertion must not leave it running).
struct Running(Child);

impl Running {
    /// Resident memory of the process, kB.
    fn rss_kb(&self) -> u64 {
        self.status_kb("VmRSS")
    }

    /// A `kB` field of `/proc/PID/status` (0 when absent).
    fn status_kb(&self, field: &str) -> u64 {
        let status = std::fs::read_to_string(format!("/proc/{}/status", self.0.id())).unwrap_or_default();
        status
            .lines()
            .find_map(|l| l.strip_prefix(field)?.strip_prefix(':'))
            .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
            .unwrap_or(0)
    }
}

impl Running {
    /// Asks the process to stop (SIGTERM) and waits for it: a clean exit.
    fn terminate(mut self) {
        // SAFETY: kill(2) on our own child's pid.
        unsafe { libc::kill(self.0.id() as libc::pid_t, libc::SIGTERM) };
        let _ = self.0.wait();
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn photopose() -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_photopose"));
    cmd.current_dir(env!("CARGO_MANIFEST_DIR")).env("RUST_LOG", "warn");
    cmd
}

fn spawn(args: &[&str]) -> Running {
    let child = photopose()
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("photopose binary");
    Running(child)
}

fn model() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/examples/rocket.model")
        .display()
        .to_string()
}

fn estimator() -> Running {
    spawn(&["estimator", "--model", &model()])
}

/// A test's view of the pose streams: every pose and truth, with the time it arrived.
struct Watcher {
    _ipc: Ipc,
    poses: PoseSubscriber,
    truth: PoseSubscriber,
    got: Vec<(PoseMsg, Instant)>,
    truths: HashMap<u64, PoseMsg>,
    /// When each truth (a frame of the camera) arrived.
    truth_times: Vec<Instant>,
}

impl Watcher {
    fn new(name: &str) -> Self {
        let ipc = Ipc::new(name).expect("iceoryx2 node");
        let poses = ipc.pose_subscriber(POSES_SERVICE).expect("poses");
        let truth = ipc.pose_subscriber(TRUTH_SERVICE).expect("truth");
        Self {
            _ipc: ipc,
            poses,
            truth,
            got: Vec::new(),
            truths: HashMap::new(),
            truth_times: Vec::new(),
        }
    }

    /// Collects for `d`.
    fn collect(&mut self, d: Duration) {
        let end = Instant::now() + d;
        while Instant::now() < end {
            self.drain();
            std::thread::sleep(Duration::from_millis(2));
        }
    }

    /// Collects until a pose arrives (true) or `d` passed (false).
    fn until_pose(&mut self, d: Duration) -> bool {
        let (end, before) = (Instant::now() + d, self.got.len());
        while Instant::now() < end {
            self.drain();
            if self.got.len() > before {
                return true;
            }
            std::thread::sleep(Duration::from_millis(2));
        }
        false
    }

    /// When the first truth (camera frame) after `t` arrived, if one did.
    fn truths_since(&self, t: Instant) -> Option<Instant> {
        self.truth_times.iter().copied().find(|&a| a >= t)
    }

    fn drain(&mut self) {
        while let Some(s) = self.poses.receive().expect("receive pose") {
            self.got.push((*s.payload(), Instant::now()));
        }
        while let Some(s) = self.truth.receive().expect("receive truth") {
            self.truths.insert(s.payload().frame_id, *s.payload());
            self.truth_times.push(Instant::now());
        }
    }
}

fn position_error(p: &PoseMsg, t: &PoseMsg) -> f64 {
    (0..3)
        .map(|i| (p.position_mm[i] - t.position_mm[i]).powi(2))
        .sum::<f64>()
        .sqrt()
}

#[test]
fn capture_and_estimator_processes_track_a_moving_card() {
    let _serial = serial();
    let mut w = Watcher::new("photopose-test-track");
    // The estimator first: processes may start in any order.
    let _estimator = estimator();
    std::thread::sleep(Duration::from_millis(300));
    let _capture = spawn(&["capture", "--speed", "150"]);
    w.collect(Duration::from_secs(8));
    let got: Vec<PoseMsg> = w.got.iter().map(|(p, _)| *p).collect();
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
        let t = w
            .truths
            .get(&p.frame_id)
            .unwrap_or_else(|| panic!("pose for unknown frame {}", p.frame_id));
        assert_eq!(p.capture_time_ns, t.capture_time_ns, "frame {}", p.frame_id);
        assert!(p.publish_time_ns > p.capture_time_ns);
    }
    // Cold start: the first pose is the acquisition.
    let first = &got[0];
    let acquisition_s = (first.publish_time_ns - first.capture_time_ns) as f64 * 1e-9;
    // Tracking error against the truth of the same frame, after acquisition.
    let errors = Samples::new(got[1..].iter().map(|p| position_error(p, &w.truths[&p.frame_id])));
    let tracking = got.iter().filter(|p| p.status == Status::Tracking as u32).count();
    let latency = Samples::new(
        got[1..]
            .iter()
            .map(|p| (p.publish_time_ns - p.capture_time_ns) as f64 * 1e-6),
    );
    let span = got.last().unwrap().frame_id - first.frame_id + 1;
    println!(
        "{} poses ({tracking} tracking) for {span} frames, acquisition {acquisition_s:.2} s, error median {:.1} mm \
         p95 {:.1} mm, capture→pose p50 {:.1} ms p99 {:.1} ms",
        got.len(),
        errors.median(),
        errors.percentile(95.0),
        latency.median(),
        latency.percentile(99.0)
    );
    assert!(
        errors.percentile(95.0) <= 10.0,
        "p95 tracking error {:.1} mm at 150 mm/s",
        errors.percentile(95.0)
    );
    assert!(acquisition_s < 1.0, "acquisition took {acquisition_s:.2} s");
    assert!(
        tracking as f64 >= 0.95 * got.len() as f64,
        "{tracking} of {} poses tracking",
        got.len()
    );
}

#[test]
fn processes_start_in_any_order_and_resume_after_a_crash() {
    let _serial = serial();
    let mut w = Watcher::new("photopose-test-restart");
    // Camera first this time.
    let capture = spawn(&["capture"]);
    std::thread::sleep(Duration::from_millis(500));
    let estimator1 = estimator();
    assert!(w.until_pose(Duration::from_secs(5)), "no pose from the first estimator");
    w.collect(Duration::from_secs(1));
    // The estimator dies without cleaning up; a new one takes over.
    drop(estimator1);
    w.collect(Duration::from_millis(200));
    let before = w.got.len();
    let restarted = Instant::now();
    let _estimator2 = estimator();
    assert!(
        w.until_pose(Duration::from_secs(5)),
        "no pose after the estimator restart"
    );
    let resumed = restarted.elapsed();
    assert!(
        resumed < Duration::from_secs(2),
        "poses resumed {resumed:?} after the estimator restart"
    );
    assert!(w.got.len() > before);
    // Now the camera dies and comes back: its frame ids start again at 0.
    w.collect(Duration::from_secs(1));
    drop(capture);
    w.collect(Duration::from_millis(300));
    let restarted = Instant::now();
    let _capture2 = spawn(&["capture"]);
    assert!(w.until_pose(Duration::from_secs(5)), "no pose after the camera restart");
    let camera_resumed = restarted.elapsed();
    w.collect(Duration::from_secs(1));
    println!("poses resumed {resumed:?} after the estimator restart, {camera_resumed:?} after the camera restart");
    assert!(
        camera_resumed < Duration::from_secs(2),
        "poses resumed {camera_resumed:?} after the camera restart"
    );
    // No frame got two poses from one estimator-camera pair: ids increase between restarts.
    let restarts = w.got.windows(2).filter(|p| p[1].0.frame_id <= p[0].0.frame_id).count();
    assert!(
        restarts <= 1,
        "frame ids went back {restarts} times (one camera restart)"
    );
}

/// A thread of a running process as the kernel sees it.
#[derive(Debug)]
struct TaskInfo {
    name: String,
    cpus: String,
    policy: i32,
    rt_priority: i32,
}

fn tasks(pid: u32) -> Vec<(u32, TaskInfo)> {
    let dir = format!("/proc/{pid}/task");
    let mut out = Vec::new();
    for entry in std::fs::read_dir(&dir).expect("task list").flatten() {
        let tid: u32 = entry.file_name().to_string_lossy().parse().expect("tid");
        let read = |f: &str| std::fs::read_to_string(entry.path().join(f)).unwrap_or_default();
        let (stat, status) = (read("stat"), read("status"));
        // Fields after the parenthesised name: state is field 3; rt_priority 40, policy 41.
        let after = &stat[stat.rfind(')').map_or(0, |i| i + 2)..];
        let field = |n: usize| after.split(' ').nth(n - 3).and_then(|v| v.parse().ok()).unwrap_or(-1);
        let cpus = status
            .lines()
            .find_map(|l| l.strip_prefix("Cpus_allowed_list:"))
            .unwrap_or("")
            .trim()
            .to_string();
        let name = read("comm").trim().to_string();
        out.push((
            tid,
            TaskInfo {
                name,
                cpus,
                policy: field(41),
                rt_priority: field(40),
            },
        ));
    }
    out
}

#[test]
fn the_estimator_applies_its_realtime_options() {
    let _serial = serial();
    let dir = scratch("realtime");
    let config = dir.join("realtime.toml");
    std::fs::write(
        &config,
        "[ga]\nthreads = 2\n[realtime]\ncpus = [1, 0]\nfifo_priority = 1\nlock_memory = true\n",
    )
    .unwrap();
    // Whether this machine lets the tests' user use SCHED_FIFO decides what to expect.
    let fifo_allowed = std::thread::spawn(|| {
        let wish = photopose::estimator::realtime::RealtimeSettings {
            fifo_priority: 1,
            ..Default::default()
        };
        photopose::estimator::realtime::apply_to_thread(&wish, 0)
            .fifo_priority
            .is_some()
    })
    .join()
    .unwrap();
    let log = dir.join("estimator.log");
    let mut w = Watcher::new("photopose-test-realtime");
    let child = photopose()
        .env("RUST_LOG", "info")
        .args(["estimator", "--model", &model(), "--config"])
        .arg(&config)
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(&log).unwrap())
        .spawn()
        .expect("photopose binary");
    let estimator = Running(child);
    let _capture = spawn(&["capture"]);
    // After the first pose the acquisition has started the fitness workers.
    assert!(w.until_pose(Duration::from_secs(8)), "no pose with realtime options");
    w.collect(Duration::from_millis(500));
    let pid = estimator.0.id();
    let tasks = tasks(pid);
    let main = &tasks.iter().find(|(tid, _)| *tid == pid).expect("main thread").1;
    let workers: Vec<&TaskInfo> = tasks
        .iter()
        .filter(|(_, t)| t.name.starts_with("photopose-fitn"))
        .map(|(_, t)| t)
        .collect();
    println!("estimator threads: main {main:?}, workers {workers:?}");
    assert_eq!(main.cpus, "1", "main thread on the first listed CPU");
    assert_eq!(workers.len(), 2, "two fitness workers");
    let mut worker_cpus: Vec<&str> = workers.iter().map(|t| t.cpus.as_str()).collect();
    worker_cpus.sort();
    assert_eq!(worker_cpus, ["0", "1"], "workers on the following CPUs in turn");
    let expected = if fifo_allowed { (1, 1) } else { (0, 0) };
    for t in workers.iter().copied().chain([main]) {
        assert_eq!((t.policy, t.rt_priority), expected, "{} scheduling", t.name);
    }
    let locked_kb = estimator.status_kb("VmLck");
    drop(estimator);
    let log = std::fs::read_to_string(&log).unwrap();
    let summary = log.lines().find(|l| l.contains("realtime:")).unwrap_or("").to_string();
    println!("VmLck {locked_kb} kB; log: {summary}");
    if summary.contains("memory locked") {
        assert!(locked_kb > 1024, "memory reported locked but VmLck is {locked_kb} kB");
    } else {
        assert!(
            log.contains("mlockall refused"),
            "memory neither locked nor refused: {log}"
        );
    }
    if !fifo_allowed {
        assert!(log.contains("SCHED_FIFO priority 1 refused"), "no warning: {log}");
    }
    assert!(summary.contains("main thread on CPU 1"), "summary: {summary}");
}

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
    assert!(w.until_pose(Duration::from_secs(8)), "no pose");
    let r = latency_json(&["--seconds", "3"]);
    println!("latency: {r}");
    let n = |k: &str| r[k].as_f64().unwrap_or_else(|| panic!("no number {k} in {r}"));
    // 3 s of a 60 fps camera (a busy machine may render fewer), a pose for nearly every frame.
    assert!((120.0..=200.0).contains(&n("frames")), "{} frames", n("frames"));
    assert!(n("poses") >= 0.9 * n("frames"), "{} poses", n("poses"));
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

/// A subscriber that takes one frame a second, and one killed while subscribed, neither
/// stall the pipeline nor grow the memory of capture or estimator.
#[test]
fn a_slow_subscriber_never_grows_memory() {
    let _serial = serial();
    let ipc = Ipc::new("photopose-test-slow").expect("iceoryx2 node");
    // A subscriber that takes one frame per second and never the rest.
    let frames = ipc.frame_subscriber().expect("frames");
    let capture = spawn(&["capture"]);
    let estimator = estimator();
    // And one that vanishes: a subscriber to frames and poses killed with SIGKILL.
    let mut vanishing = Some(spawn(&["latency", "--seconds", "60"]));
    let mut w = Watcher::new("photopose-test-slow-poses");
    let mut rss = Vec::new();
    let mut poses_per_second = Vec::new();
    for second in 0..8 {
        let before = w.got.len();
        w.collect(Duration::from_secs(1));
        poses_per_second.push(w.got.len() - before);
        if let Some(frame) = frames.receive().expect("receive") {
            assert!(frame.payload().len() >= 1280 * 720 * 6);
        }
        if second == 2 {
            drop(vanishing.take());
        }
        if second >= 2 {
            rss.push((capture.rss_kb(), estimator.rss_kb()));
        }
    }
    println!("poses per second: {poses_per_second:?}");
    assert!(
        poses_per_second[3..].iter().all(|&n| n > 0),
        "the pipeline stalled behind a slow or vanished subscriber: {poses_per_second:?}"
    );
    let (first, last) = (rss[0], *rss.last().unwrap());
    println!(
        "resident memory, first → last: capture {} → {} kB, estimator {} → {} kB",
        first.0, last.0, first.1, last.1
    );
    assert!(
        last.0 <= first.0 + 2048,
        "capture grew from {} to {} kB",
        first.0,
        last.0
    );
    assert!(
        last.1 <= first.1 + 2048,
        "estimator grew from {} to {} kB",
        first.1,
        last.1
    );
}

#[test]
fn replay_plays_a_recording_with_its_truth() {
    let _serial = serial();
    let dir = scratch("replay");
    let rec = dir.join("rec");
    let out = photopose()
        .args(["capture", "--fps", "20", "--seconds", "1.5", "--record"])
        .arg(&rec)
        .output()
        .expect("record");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let csv = std::fs::read_to_string(rec.join("frames.csv")).expect("frames.csv");
    let recorded = csv.lines().count() - 1;
    assert!(recorded >= 10, "{recorded} frames recorded");

    let mut w = Watcher::new("photopose-test-replay");
    let _estimator = estimator();
    std::thread::sleep(Duration::from_millis(300));
    let replay = spawn(&["capture", "--source", &format!("replay:{}", rec.display())]);
    w.collect(Duration::from_secs(3));
    drop(replay);
    assert_eq!(
        w.truths.len(),
        recorded,
        "every recorded frame is replayed with its truth"
    );
    let tracked: Vec<f64> = w.got[1..]
        .iter()
        .map(|(p, _)| position_error(p, &w.truths[&p.frame_id]))
        .collect();
    assert!(!tracked.is_empty(), "poses for the replayed frames");
    let errors = Samples::new(tracked);
    println!(
        "{} poses on {recorded} replayed frames, error median {:.1} mm",
        w.got.len(),
        errors.median()
    );
    assert!(
        errors.median() <= 10.0,
        "median error {:.1} mm on the replay",
        errors.median()
    );
    // A corrupt frame: one line naming the file, non-zero exit.
    std::fs::write(rec.join("000003.png"), b"not a png").unwrap();
    let out = photopose()
        .args([
            "capture",
            "--source",
            &format!("replay:{}", rec.display()),
            "--fps",
            "100",
        ])
        .output()
        .expect("replay");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("000003.png"), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
}

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

/// `tools/pose_client.py --json` on `service`, its stdout and stderr read by threads.
struct PythonClient {
    process: Running,
    stdout: JoinHandle<String>,
    stderr: JoinHandle<String>,
}

impl PythonClient {
    fn spawn(service: &str, count: usize) -> Self {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
        let mut child = Command::new("python3")
            .arg(dir.join("tools/pose_client.py"))
            .args([
                "--service",
                service,
                "--json",
                "--count",
                &count.to_string(),
                "--seconds",
                "20",
            ])
            .current_dir(dir)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("python3");
        let read = |mut pipe: Box<dyn Read + Send>| {
            std::thread::spawn(move || {
                let mut text = String::new();
                let _ = pipe.read_to_string(&mut text);
                text
            })
        };
        let stdout = read(Box::new(child.stdout.take().unwrap()));
        let stderr = read(Box::new(child.stderr.take().unwrap()));
        Self {
            process: Running(child),
            stdout,
            stderr,
        }
    }

    /// Whether the client has exited.
    fn done(&mut self) -> bool {
        self.process.0.try_wait().expect("python3 status").is_some()
    }

    /// Waits for the client; its output lines, after asserting it succeeded.
    fn finish(mut self) -> Vec<String> {
        let status = self.process.0.wait().expect("python3 status");
        let stdout = self.stdout.join().unwrap();
        let stderr = self.stderr.join().unwrap();
        assert!(
            status.success(),
            "pose_client.py: {status}\nstderr: {stderr}\nstdout: {stdout}"
        );
        stdout.lines().map(str::to_owned).collect()
    }
}

/// The text of `key`'s value in a line of `pose_client.py --json` (Python's json.dumps:
/// `"key": value, `), so that floats are parsed exactly by Rust, not by serde_json's
/// best-effort float parser.
fn json_text<'a>(line: &'a str, key: &str) -> &'a str {
    let tag = format!("\"{key}\": ");
    let start = line.find(&tag).unwrap_or_else(|| panic!("no {key} in {line}")) + tag.len();
    let rest = &line[start..];
    let end = if rest.starts_with('[') {
        rest.find(']').map(|i| i + 1)
    } else {
        rest.find([',', '}'])
    };
    &rest[..end.unwrap_or_else(|| panic!("unterminated {key} in {line}"))]
}

fn json_u64(line: &str, key: &str) -> u64 {
    let text = json_text(line, key);
    text.parse().unwrap_or_else(|e| panic!("{key} = {text}: {e}"))
}

/// The bit patterns of a float or float array (Python prints the shortest repr that
/// round-trips, Rust parses it correctly rounded: equal bits or a real difference).
fn json_f64_bits(line: &str, key: &str) -> Vec<u64> {
    json_text(line, key)
        .trim_start_matches('[')
        .trim_end_matches(']')
        .split(',')
        .map(|t| {
            t.trim()
                .parse::<f64>()
                .unwrap_or_else(|e| panic!("{key} = {t}: {e}"))
                .to_bits()
        })
        .collect()
}

fn bits(values: &[f64]) -> Vec<u64> {
    values.iter().map(|v| v.to_bits()).collect()
}

/// Asserts that every pose the Python client printed is, field by field and bit by bit,
/// the pose Rust received (or sent) with that frame id.
fn assert_python_saw(lines: &[String], rust: &HashMap<u64, PoseMsg>) {
    let mut last: Option<u64> = None;
    for line in lines {
        let value: serde_json::Value = serde_json::from_str(line).unwrap_or_else(|e| panic!("{e}: {line}"));
        let frame_id = json_u64(line, "frame_id");
        assert!(last.is_none_or(|l| frame_id > l), "frame {frame_id} after {last:?}");
        last = Some(frame_id);
        let p = rust
            .get(&frame_id)
            .unwrap_or_else(|| panic!("Python printed frame {frame_id} that Rust never saw: {line}"));
        assert_eq!(json_u64(line, "capture_time_ns"), p.capture_time_ns, "{line}");
        assert_eq!(json_u64(line, "publish_time_ns"), p.publish_time_ns, "{line}");
        assert_eq!(
            json_f64_bits(line, "position_mm"),
            bits(&p.position_mm),
            "{line} vs {p:?}"
        );
        assert_eq!(
            json_f64_bits(line, "orientation_wxyz"),
            bits(&p.orientation_wxyz),
            "{line} vs {p:?}"
        );
        assert_eq!(json_f64_bits(line, "size_mm"), bits(&p.size_mm), "{line} vs {p:?}");
        assert_eq!(json_f64_bits(line, "fitness"), bits(&[p.fitness]), "{line} vs {p:?}");
        assert_eq!(json_u64(line, "generations"), u64::from(p.generations), "{line}");
        assert_eq!(json_u64(line, "status"), u64::from(p.status), "{line}");
        let name = ["tracking", "searching", "lost"][p.status as usize];
        assert_eq!(value["status_name"], name, "{line}");
    }
}

/// A pose with every field different from zero and from the others, with floats whose
/// shortest decimal form needs 17 digits or an exponent.
fn distinct_pose(i: u64) -> PoseMsg {
    let f = i as f64;
    let now = monotonic_ns();
    PoseMsg {
        frame_id: 1_000_000 + i,
        capture_time_ns: now - 12_345_678,
        publish_time_ns: now,
        position_mm: [0.1 + f, -1.0 / 3.0 - f, 650.0 + f / 7.0],
        orientation_wxyz: [1.0 - 1e-12 * f, 1.5e-5, -2.5e-7 * (f + 1.0), 1.0 / 3.0],
        size_mm: [180.0 + 1e-9 * f, 159.0 / 7.0],
        fitness: 2.0 / 3.0 + 1e-3 * f,
        generations: 40 + i as u32,
        status: (i % 3) as u32,
    }
}

fn python_has_iceoryx2() -> bool {
    Command::new("python3")
        .args(["-c", "import iceoryx2"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

#[test]
fn python_client_reads_the_pose_layout() {
    let _serial = serial();
    if !python_has_iceoryx2() {
        println!("skipped: python3 cannot import iceoryx2 (pip install iceoryx2==0.10.0)");
        return;
    }
    let ipc = Ipc::new("photopose-test-pyclient").expect("iceoryx2 node");

    // The ground truth of the synthetic camera, received by Rust and by Python.
    let truth = ipc.pose_subscriber(TRUTH_SERVICE).expect("truth");
    let _capture = spawn(&["capture", "--seconds", "6"]);
    let mut python = PythonClient::spawn(TRUTH_SERVICE, 30);
    let mut truths: HashMap<u64, PoseMsg> = HashMap::new();
    let start = Instant::now();
    loop {
        while let Some(s) = truth.receive().expect("receive truth") {
            truths.insert(s.payload().frame_id, *s.payload());
        }
        if python.done() {
            break;
        }
        assert!(
            start.elapsed() < Duration::from_secs(25),
            "pose_client.py did not finish"
        );
        std::thread::sleep(Duration::from_millis(2));
    }
    while let Some(s) = truth.receive().expect("receive truth") {
        truths.insert(s.payload().frame_id, *s.payload());
    }
    let truth_lines = python.finish();
    assert_eq!(truth_lines.len(), 30, "{truth_lines:?}");
    assert_python_saw(&truth_lines, &truths);
    assert!(truths.values().any(|t| t.position_mm[2] > 500.0 && t.size_mm[0] > 0.0));

    // The truth leaves fitness, generations, status and publish time at zero: poses with
    // every field set, published by this test on a service of its own.
    let service = "photopose/test/pyclient";
    let publisher = ipc.pose_publisher(service).expect("test publisher");
    let mut python = PythonClient::spawn(service, 6);
    let mut sent: HashMap<u64, PoseMsg> = HashMap::new();
    let start = Instant::now();
    for i in 0.. {
        if python.done() {
            break;
        }
        assert!(
            start.elapsed() < Duration::from_secs(25),
            "pose_client.py did not finish"
        );
        let pose = distinct_pose(i);
        send_pose(&publisher, pose).expect("send");
        sent.insert(pose.frame_id, pose);
        std::thread::sleep(Duration::from_millis(20));
    }
    let lines = python.finish();
    assert_eq!(lines.len(), 6, "{lines:?}");
    assert_python_saw(&lines, &sent);
    println!(
        "pose_client.py printed 30 truth poses and 6 test poses, all bit-identical to Rust's; first: {}",
        truth_lines[0]
    );
}

/// iceoryx2's files: shared memory (`/dev/shm/iox2_*`) and everything under its root
/// directory (`/tmp/iceoryx2`: service and node records, event sockets), with their modes.
/// The machine-wide management segment every iceoryx2 process shares is left out.
fn ipc_entries() -> Vec<(PathBuf, u32)> {
    use std::os::unix::fs::PermissionsExt;
    fn walk(dir: &Path, out: &mut Vec<(PathBuf, u32)>, keep: &dyn Fn(&str) -> bool) {
        let Ok(entries) = std::fs::read_dir(dir) else { return };
        for e in entries.flatten() {
            let (path, name) = (e.path(), e.file_name().to_string_lossy().to_string());
            let Ok(meta) = std::fs::symlink_metadata(&path) else {
                continue;
            };
            if meta.is_dir() {
                walk(&path, out, &|_| true);
            } else if keep(&name) && !name.ends_with(".global_mgmt") {
                out.push((path, meta.permissions().mode() & 0o777));
            }
        }
    }
    let mut out = Vec::new();
    walk(Path::new("/dev/shm"), &mut out, &|n| n.starts_with("iox2_"));
    walk(Path::new("/tmp/iceoryx2"), &mut out, &|_| true);
    out.sort();
    out
}

/// SIGKILL of the estimator, the camera or both at random moments, 20 times, each
/// restarted at once: poses resume within 2 s every time, the controller's client flags
/// the newest pose stale while no pose comes, and iceoryx2's files do not accumulate
/// (the restarted processes clean up what the killed ones left).
#[test]
fn twenty_random_kills_and_restarts() {
    use rand::{Rng, SeedableRng};
    let _serial = serial();
    let before = ipc_entries();
    let mut rng = rand::rngs::StdRng::seed_from_u64(2023);
    let mut w = Watcher::new("photopose-test-kill");
    let deadline = Duration::from_millis(100);
    let mut client = PoseClient::connect("photopose-test-kill-client", deadline).expect("client");
    let mut capture = Some(spawn(&["capture"]));
    let mut estimator_p = Some(estimator());
    assert!(w.until_pose(Duration::from_secs(10)), "no first pose");
    let (mut resumed, mut counts) = (Vec::new(), Vec::new());
    for cycle in 0..20 {
        // A random moment: sometimes still acquiring, sometimes long tracking.
        w.collect(Duration::from_millis(rng.random_range(50..1500)));
        let victim = ["estimator", "capture", "both"][rng.random_range(0..3)];
        if victim != "capture" {
            drop(estimator_p.take()); // SIGKILL
        }
        if victim != "estimator" {
            drop(capture.take());
        }
        w.collect(deadline + Duration::from_millis(rng.random_range(50..300)));
        client.poll().expect("poll");
        let latest = client.latest().expect("a pose before the kill");
        assert!(
            latest.stale && !latest.usable(),
            "cycle {cycle} ({victim} killed): newest pose not stale: {latest:?}"
        );
        let restarted = Instant::now();
        capture.get_or_insert_with(|| spawn(&["capture"]));
        estimator_p.get_or_insert_with(estimator);
        assert!(
            w.until_pose(Duration::from_secs(6)),
            "cycle {cycle}: no pose within 6 s after restarting the {victim}"
        );
        let took = restarted.elapsed();
        // A restarted synthetic camera first loads its scene and renders the wall; the
        // estimator's deadline runs from the camera's first frame.
        let first_pose = w.got.last().expect("a pose").1;
        let since_frames = match victim {
            "estimator" => took,
            _ => {
                let first_frame = w.truths_since(restarted).expect("a frame of the new camera");
                first_pose.saturating_duration_since(first_frame)
            }
        };
        assert!(
            since_frames < Duration::from_secs(2),
            "cycle {cycle}: poses resumed {since_frames:?} after the {victim} restart ({took:?} after the restart)"
        );
        // The client sees a fresh pose again.
        let fresh_by = Instant::now() + Duration::from_secs(3);
        while client.latest().is_none_or(|l| l.stale) && Instant::now() < fresh_by {
            client.poll().expect("poll");
            std::thread::sleep(Duration::from_millis(2));
        }
        assert!(
            client.latest().is_some_and(|l| !l.stale),
            "cycle {cycle}: no fresh pose"
        );
        resumed.push((victim, took, since_frames));
        counts.push(ipc_entries().len());
    }
    // A clean stop of the last pair and of the test's own nodes.
    for p in [capture.take(), estimator_p.take()].into_iter().flatten() {
        p.terminate();
    }
    drop((w, client));
    let after = ipc_entries();
    let ms = |d: &Duration| format!("{:.0}", d.as_secs_f64() * 1e3);
    let lines: Vec<String> = resumed
        .iter()
        .map(|(v, t, f)| format!("{v} {} ({} after the first frame)", ms(t), ms(f)))
        .collect();
    println!("poses resumed after restart (ms): {}", lines.join(", "));
    println!(
        "iceoryx2 entries: {} before, {counts:?} while running after each restart, {} after",
        before.len(),
        after.len()
    );
    assert!(
        counts[15..].iter().max() <= counts[..5].iter().max(),
        "entries accumulate: {counts:?}"
    );
    let gone: Vec<_> = after.iter().filter(|e| !before.contains(e)).collect();
    assert_eq!(after.len(), before.len(), "entries left behind: {gone:?}");
}

/// Every file iceoryx2 makes for photopose (shared memory, records, sockets) is readable
/// and writable by its user only.
#[test]
fn shared_memory_is_private_to_the_user() {
    let _serial = serial();
    let mut w = Watcher::new("photopose-test-access");
    let _capture = spawn(&["capture"]);
    let _estimator = estimator();
    assert!(w.until_pose(Duration::from_secs(10)), "no pose");
    let entries = ipc_entries();
    let shm = entries.iter().filter(|(p, _)| p.starts_with("/dev/shm")).count();
    println!("{} entries ({shm} in /dev/shm)", entries.len());
    assert!(shm >= 6, "frames, poses, truth and their events: {entries:?}");
    let open: Vec<_> = entries.iter().filter(|(_, mode)| mode & 0o077 != 0).collect();
    assert!(open.is_empty(), "accessible to group or others: {open:?}");
}

/// Frames whose header disagrees with the payload reach the estimator over shared
/// memory: it skips and counts each, keeps running, and tracks the next good frame.
#[test]
fn the_estimator_skips_frames_whose_header_disagrees_with_the_payload() {
    use photopose::transport::ipc::wake_up;
    use photopose::transport::messages::{pixel_format, FrameHeader, FRAMES_SERVICE};
    let _serial = serial();
    let frame = image::open(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/examples/rocket-frame.jpg"))
        .expect("example frame")
        .to_rgb8();
    let (w, h) = (frame.width() / 2, frame.height());
    let stride = 2 * w * 3;
    let good = FrameHeader {
        width: w,
        height: h,
        pixel_format: pixel_format::RGB8,
        row_stride: stride,
        ..Default::default()
    };
    let len = (stride * h) as usize;
    let bad = [
        (
            FrameHeader {
                pixel_format: 7,
                ..good
            },
            len,
        ),
        (FrameHeader { width: 0, ..good }, len),
        (
            FrameHeader {
                row_stride: stride - 3,
                ..good
            },
            len,
        ),
        (good, len - 1),
        (FrameHeader { height: h + 1, ..good }, len),
    ];
    let ipc = Ipc::new("photopose-test-bad-frames").expect("node");
    let publisher = ipc.frame_publisher(len).expect("frame publisher");
    let waker = ipc.waker(FRAMES_SERVICE).expect("waker");
    let mut w = Watcher::new("photopose-test-bad-frames-poses");
    let process = photopose()
        .args(["estimator", "--model", &model(), "--seconds", "8"])
        .env("RUST_LOG", "photopose=info")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("estimator");
    let mut process = Running(process);
    std::thread::sleep(Duration::from_millis(800));
    let send = |id: u64, header: FrameHeader, len: usize| {
        let mut sample = publisher.loan_slice(len).expect("loan");
        let n = len.min(frame.as_raw().len());
        sample.payload_mut()[..n].copy_from_slice(&frame.as_raw()[..n]);
        *sample.user_header_mut() = FrameHeader {
            frame_id: id,
            capture_time_ns: monotonic_ns(),
            publish_time_ns: monotonic_ns(),
            ..header
        };
        sample.send().expect("send");
        wake_up(&waker);
        // One at a time: the estimator always takes the newest frame.
        std::thread::sleep(Duration::from_millis(200));
    };
    for (i, (header, len)) in bad.into_iter().enumerate() {
        send(i as u64, header, len);
    }
    assert!(
        w.got.is_empty() && !w.until_pose(Duration::from_millis(100)),
        "a pose for a bad frame"
    );
    send(10, good, len);
    assert!(
        w.until_pose(Duration::from_secs(5)),
        "no pose for the good frame after the bad ones"
    );
    assert_eq!(w.got[0].0.frame_id, 10);
    let mut err = String::new();
    process.0.wait().expect("estimator exits after --seconds");
    process
        .0
        .stderr
        .take()
        .expect("stderr")
        .read_to_string(&mut err)
        .unwrap();
    assert!(
        err.contains("estimator: 1 frames processed, 0 dropped, skipped: 1 unknown pixel format, 1 empty image, 1 short stride, 2 wrong length"),
        "{err}"
    );
    for reason in [
        "unknown pixel format code 7",
        "empty image (0x720 per eye)",
        "row stride 7677 is shorter",
    ] {
        assert!(err.contains(reason), "{reason:?} not logged: {err}");
    }
}
