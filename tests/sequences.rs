//! Tracking sequences of a robot cell, in process: a card photo moving in front of a real
//! photograph, filmed by the example ZED 2i at HD, with motion blur, changing light,
//! occluders, leaving the view and approaching the camera. The stream tracker sees the
//! frames the estimator process would: a whole-frame search (an acquisition, or the
//! relocation after it) takes time, and the frames that arrive meanwhile are dropped.
//! How long varies in the processes, and a take's outcome with it, so each take is
//! played at three timings ([`play::TIMINGS`]).
//!
//! `tracking_sequences` (`cargo test --test integration -- --nocapture tracking_sequences`,
//! about 2 minutes; `TAKES=light,leave` for some) plays every take, prints the success tables and writes them to
//! `target/sequences/sequences.md`. Success, as the held-out sequences count it: the
//! share of frames with at least 60 % of the card visible that got a `tracking` pose
//! within 20 mm, 10° and 10 % of the truth. The targets are reported, reached
//! or not; the test asserts that no take has a `tracking` pose while the card is out of
//! view, and each take's regression floor ([`FLOORS`]).

mod play;

use photopose::capture::scenario::Scenario;

use play::play;

/// Regression floors of each take's median success share over the timings: the
/// figures of 2026-12-03 (sweep 3 %, sweep-60fps 0 %, yuyv 41 %, light 73 %, occlude 9 %,
/// leave 20 %, approach 35 %) less a margin. They catch a change that makes tracking
/// worse; the target (95 % at every timing) is reported, reached or not, and not
/// asserted.
const FLOORS: [(&str, f64); 7] = [
    ("sweep", 0.0),
    ("sweep-60fps", 0.0),
    ("yuyv", 0.30),
    ("light", 0.60),
    ("occlude", 0.05),
    ("leave", 0.12),
    ("approach", 0.25),
];

/// A ceiling on the `tracking` poses more than 50 mm or 20° off, over every take and
/// timing: 18 on 2026-12-03 (9 on `sweep`, 9 on `yuyv`: tilts drifting while tracked),
/// after the texture test of tracking frames in doubt took it down from 101 (70 on
/// `sweep-60fps`, 20 on `occlude`). The target is 0.
const WRONG_CEILING: usize = 18;

/// Every take at every timing: the tables, what happened in it, the promises, the floors
/// and the ceiling.
#[test]
fn tracking_sequences() {
    // `TAKES=light,occlude` plays only those takes.
    let only = std::env::var("TAKES").ok();
    let chosen = |t: &Scenario| only.as_deref().is_none_or(|o| o.split(',').any(|n| n == t.name));
    let mut takes = Vec::new();
    for take in Scenario::all().into_iter().filter(chosen) {
        let plays: Vec<_> = play::TIMINGS.iter().map(|&timing| play(&take, timing)).collect();
        for played in &plays {
            println!("{}", played.timeline());
            println!("{}", played.row());
        }
        takes.push(plays);
    }
    play::report(&takes);
    for plays in &takes {
        play::assert_promises(plays);
        let median = play::Takes(plays).median_success();
        let name = plays[0].name;
        let floor = FLOORS.iter().find(|(n, _)| *n == name).map_or(0.0, |(_, f)| *f);
        assert!(
            median >= floor,
            "{name}: median success {median:.2} below its floor {floor}"
        );
    }
    if only.is_none() {
        let wrong: usize = takes.iter().flatten().map(|p| p.wrong()).sum();
        assert!(
            wrong <= WRONG_CEILING,
            "{wrong} wrong tracking poses, more than {WRONG_CEILING}"
        );
    }
}
