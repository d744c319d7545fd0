//! Tracking sequences of a robot cell, in process: a card photo moving in front of a real
//! photograph, filmed by the example ZED 2i at HD, with motion blur, changing light,
//! occluders, leaving the view and approaching the camera. The stream tracker sees the
//! frames the estimator process would: a whole-frame search (an acquisition, or the
//! relocation after it) takes time, and the frames that arrive meanwhile are dropped
//! ([`ACQUISITION_S`], [`WHOLE_FRAME_S`]).
//!
//! `tracking_sequences` (`cargo test --test integration -- --nocapture tracking_sequences`,
//! about a minute; `TAKES=light,leave` for some) plays every take, prints the success table and writes it to
//! `target/sequences/sequences.md`. Success, as the held-out sequences count it: the
//! share of frames with at least 60 % of the card visible that got a `tracking` pose
//! within 20 mm, 10° and 10 % of the truth. The targets are reported, reached
//! or not; the test asserts that no take has a `tracking` pose while the card is out of
//! view, and each take's regression floor ([`FLOORS`]).

mod play;

use photopose::capture::scenario::Scenario;

use play::play;

/// Regression floors of the success share per take: the figures of 2026-12-03 (sweep
/// 48 %, sweep-60fps 0 %, yuyv 28 %, light 74 %, occlude 11 %, leave 25 %, approach 35 %)
/// less a margin. They catch a change that makes tracking worse; the target
/// (95 %) is reported, reached or not, and not asserted.
const FLOORS: [(&str, f64); 7] = [
    ("sweep", 0.40),
    ("sweep-60fps", 0.0),
    ("yuyv", 0.20),
    ("light", 0.65),
    ("occlude", 0.08),
    ("leave", 0.20),
    ("approach", 0.30),
];

/// Every take: the table, what happened in it, the promises and the floors.
#[test]
fn tracking_sequences() {
    // `TAKES=light,occlude` plays only those takes.
    let only = std::env::var("TAKES").ok();
    let chosen = |t: &Scenario| only.as_deref().is_none_or(|o| o.split(',').any(|n| n == t.name));
    let mut rows = Vec::new();
    for take in Scenario::all().into_iter().filter(chosen) {
        let played = play(&take);
        println!("{}", played.timeline());
        println!("{}", played.row());
        rows.push(played);
    }
    play::report(&rows);
    play::assert_promises(&rows);
    for p in &rows {
        let floor = FLOORS.iter().find(|(n, _)| *n == p.name).map_or(0.0, |(_, f)| *f);
        assert!(
            p.success() >= floor,
            "{}: success {:.2} below its floor {floor}",
            p.name,
            p.success()
        );
    }
}
