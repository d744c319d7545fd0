//! The estimator's `[realtime]` options as the kernel sees them: CPU affinity, SCHED_FIFO
//! and locked memory of its threads.

use std::process::Stdio;
use std::time::Duration;

use crate::common::scratch;
use crate::process::{model, photopose, serial, spawn, Running, Watcher};

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
