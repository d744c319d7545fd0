//! Processes that start in any order, crash and come back: poses resume within 2 s and
//! iceoryx2's files do not pile up.

use std::time::{Duration, Instant};

use photopose::client::PoseClient;

use crate::process::{estimator, ipc_entries, serial, spawn, Watcher};

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
        // estimator's deadline runs from the camera's first frame, known by its truth.
        // The truth comes on a service of its own, which the watcher may join after the
        // first poses: a pose then shows that a frame came by its own arrival.
        let first_pose = w.got.last().expect("a pose").1;
        let since_frames = match victim {
            "estimator" => took,
            _ => {
                let by = Instant::now() + Duration::from_secs(1);
                while w.truths_since(restarted).is_none() && Instant::now() < by {
                    w.collect(Duration::from_millis(10));
                }
                let first_frame = w.truths_since(restarted).map_or(first_pose, |t| t.min(first_pose));
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
