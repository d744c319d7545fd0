//! The processes under test and a test's view of what they publish: one test at a time,
//! `photopose` children killed when dropped, the pose and truth streams, and iceoryx2's
//! files on disk.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant};

use photopose::transport::ipc::{receive_poses, Ipc, PoseSubscriber};
use photopose::transport::messages::{PoseMsg, PoseSet, Status, POSES_SERVICE, TRUTH_SERVICE};

use crate::common::{data, repo};

/// One process test at a time (they use the same iceoryx2 services).
pub fn serial() -> MutexGuard<'static, ()> {
    static LOCK: Mutex<()> = Mutex::new(());
    LOCK.lock().unwrap_or_else(|e| e.into_inner())
}

/// Kills a child process when dropped (a failed assertion must not leave it running).
pub struct Running(pub Child);

impl Running {
    /// Resident memory of the process, kB.
    pub fn rss_kb(&self) -> u64 {
        self.status_kb("VmRSS")
    }

    /// A `kB` field of `/proc/PID/status` (0 when absent).
    pub fn status_kb(&self, field: &str) -> u64 {
        let status = std::fs::read_to_string(format!("/proc/{}/status", self.0.id())).unwrap_or_default();
        status
            .lines()
            .find_map(|l| l.strip_prefix(field)?.strip_prefix(':'))
            .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
            .unwrap_or(0)
    }

    /// Asks the process to stop (SIGTERM) and waits for it: a clean exit.
    pub fn terminate(mut self) {
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

/// The `photopose` binary, run from the repository root, logging warnings only.
pub fn photopose() -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_photopose"));
    cmd.current_dir(repo("")).env("RUST_LOG", "warn");
    cmd
}

/// `photopose ARGS` in the background, its output discarded.
pub fn spawn(args: &[&str]) -> Running {
    let child = photopose()
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("photopose binary");
    Running(child)
}

/// The example rocket model, as an argument.
pub fn model() -> String {
    data("examples/rocket.model").display().to_string()
}

/// `photopose estimator` with the example rocket model.
pub fn estimator() -> Running {
    spawn(&["estimator", "--model", &model()])
}

/// A test's view of the pose streams: every pose and truth, with the time it arrived.
pub struct Watcher {
    _ipc: Ipc,
    poses: PoseSubscriber,
    truth: PoseSubscriber,
    /// The first object's poses (the only one of a single-model estimator).
    pub got: Vec<(PoseMsg, Instant)>,
    /// The first object's truth by frame.
    pub truths: HashMap<u64, PoseMsg>,
    /// Every pose set.
    pub sets: Vec<PoseSet>,
    /// Every truth set by frame.
    pub truth_sets: HashMap<u64, PoseSet>,
    /// When each truth (a frame of the camera) arrived.
    pub truth_times: Vec<Instant>,
}

impl Watcher {
    pub fn new(name: &str) -> Self {
        let ipc = Ipc::new(name).expect("iceoryx2 node");
        let poses = ipc.pose_subscriber(POSES_SERVICE).expect("poses");
        let truth = ipc.pose_subscriber(TRUTH_SERVICE).expect("truth");
        Self {
            _ipc: ipc,
            poses,
            truth,
            got: Vec::new(),
            truths: HashMap::new(),
            sets: Vec::new(),
            truth_sets: HashMap::new(),
            truth_times: Vec::new(),
        }
    }

    /// Collects for `d`.
    pub fn collect(&mut self, d: Duration) {
        let end = Instant::now() + d;
        while Instant::now() < end {
            self.drain();
            std::thread::sleep(Duration::from_millis(2));
        }
    }

    /// Collects until a pose arrives (true) or `d` passed (false).
    pub fn until_pose(&mut self, d: Duration) -> bool {
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

    /// Waits at most `d` for a pose of a tracking frame (status `tracking`, no more
    /// generations than a tracking frame runs): the acquisition and the relocation after
    /// it are over. True if one came.
    pub fn until_tracking(&mut self, d: Duration) -> bool {
        let per_frame = photopose::config::Config::load(None)
            .expect("default configuration")
            .tracking
            .generations_per_frame as u32;
        let end = Instant::now() + d;
        while Instant::now() < end {
            self.drain();
            let last = self.got.last().map(|(p, _)| p);
            if last.is_some_and(|p| p.status == Status::Tracking as u32 && p.generations <= per_frame) {
                return true;
            }
            std::thread::sleep(Duration::from_millis(2));
        }
        false
    }

    /// When the first truth (camera frame) after `t` arrived, if one did.
    pub fn truths_since(&self, t: Instant) -> Option<Instant> {
        self.truth_times.iter().copied().find(|&a| a >= t)
    }

    pub fn drain(&mut self) {
        while let Some(set) = receive_poses(&self.poses).expect("receive poses") {
            if let Some(&p) = set.first() {
                self.got.push((p, Instant::now()));
            }
            self.sets.push(set);
        }
        while let Some(set) = receive_poses(&self.truth).expect("receive truth") {
            if let Some(&t) = set.first() {
                self.truths.insert(t.frame_id, t);
                self.truth_sets.insert(t.frame_id, set);
            }
            self.truth_times.push(Instant::now());
        }
    }
}

/// Distance between two poses' positions, mm.
pub fn position_error(p: &PoseMsg, t: &PoseMsg) -> f64 {
    (0..3)
        .map(|i| (p.position_mm[i] - t.position_mm[i]).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// iceoryx2's files: shared memory (`/dev/shm/iox2_*`) and everything under its root
/// directory (`/tmp/iceoryx2`: service and node records, event sockets), with their modes.
/// The machine-wide management segment every iceoryx2 process shares is left out.
pub fn ipc_entries() -> Vec<(PathBuf, u32)> {
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

/// A child whose stdout and stderr are read by threads while it runs (the Python clients).
pub struct Piped {
    pub process: Running,
    stdout: std::thread::JoinHandle<String>,
    stderr: std::thread::JoinHandle<String>,
}

impl Piped {
    /// Spawns `cmd` with stdin closed and both outputs piped.
    pub fn spawn(cmd: &mut Command) -> Self {
        use std::io::Read;
        let mut child = cmd
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("spawn");
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

    /// Waits for the child: its exit status, stdout and stderr.
    pub fn finish(mut self) -> (std::process::ExitStatus, String, String) {
        let status = self.process.0.wait().expect("exit status");
        (status, self.stdout.join().unwrap(), self.stderr.join().unwrap())
    }
}
