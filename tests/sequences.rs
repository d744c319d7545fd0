//! Tracking sequences of a robot cell, in process: a card photo moving in front of a real
//! photograph, filmed by the example ZED 2i at HD, with motion blur, changing light,
//! occluders, leaving the view and approaching the camera. The stream tracker sees the
//! frames the estimator process would: a whole-frame search (an acquisition, or a
//! recovery) takes time; the frames that arrive meanwhile get no pose of the object and
//! are kept, and the tracker follows it through them before it takes the newest frame.
//! How long a search takes varies in the processes, and a take's outcome with it, so
//! each take is played at three timings ([`play::TIMINGS`]).
//!
//! `tracking_sequences` (`cargo test --test integration -- --nocapture tracking_sequences`,
//! about 4 minutes) plays every take, prints the success tables and writes them to
//! `target/sequences/sequences.md`. `TAKES=light,leave` plays some takes, `TIMING=1` one
//! timing (0–2), `TRACK_SEED=7` another seed of the tracker; the floors and the ceiling
//! are asserted only on the whole run at the configured seed. Success, as the held-out
//! sequences count it: the share of frames with at least 60 % of the card visible that
//! got a `tracking` pose within 20 mm, 10° and 10 % of the truth. The targets
//! are reported, reached or not; the test asserts that no take has a `tracking` pose
//! while the card is out of view, each take's regression floor ([`FLOORS`]) and the
//! ceiling on wrong poses ([`WRONG_CEILING`]). `crossed_takes` (ignored; CI runs it in
//! the optimised test build) plays each take with other takes' cards and walls.

mod play;

use photopose::capture::scenario::film::Film;
use photopose::capture::scenario::{Judged, Scenario, GOOD};
use photopose::estimator::tracking::{Estimate, StreamTracker, TrackState};

use play::play;

/// Regression floors of each take's median success share over the timings: the
/// figures of 2026-12-05 (sweep 82 %, sweep-60fps 49 %, yuyv 82 %, light 87 %), of
/// the evening, with the card followed beyond the search space and tracking frames
/// reading the eyes' similarity on the card alone (leave 60 %, approach 75 %), and of
/// that night, with the size held and the eyes' agreement read beside an occluder (occlude
/// 80 %; 72–81 % over the tracker's seeds 1–7), less a margin. They catch a change
/// that makes tracking worse; the target (95 % at every timing) is reported,
/// reached or not, and not asserted.
const FLOORS: [(&str, f64); 7] = [
    ("sweep", 0.70),
    ("sweep-60fps", 0.35),
    ("yuyv", 0.70),
    ("light", 0.74),
    ("occlude", 0.65),
    ("leave", 0.50),
    ("approach", 0.60),
];

/// A ceiling on the `tracking` poses more than 50 mm or 20° off, over every take and
/// timing: 0 on 2026-12-05 (and with the tracker seeded 7), 3 before (on `sweep`: the
/// tilt 21–23° off, the position within 6 mm), 18 before the climb
/// (docs/tracking-sequences.md). The target is 0.
const WRONG_CEILING: usize = 1;

/// Every take at every timing: the tables, what happened in it, the promises, the floors
/// and the ceiling.
#[test]
fn tracking_sequences() {
    // `TAKES=light,occlude` plays only those takes.
    let only = std::env::var("TAKES").ok();
    let chosen = |t: &Scenario| only.as_deref().is_none_or(|o| o.split(',').any(|n| n == t.name));
    // `TIMING=1` plays one timing; `TRACK_SEED=7` another seed (see `play::play`).
    let pick = std::env::var("TIMING").ok().and_then(|s| s.parse::<usize>().ok());
    let configured = pick.is_none() && std::env::var("TRACK_SEED").is_err();
    let mut takes = Vec::new();
    for take in Scenario::all().into_iter().filter(chosen) {
        let plays: Vec<_> = play::TIMINGS
            .iter()
            .enumerate()
            .filter(|(k, _)| pick.is_none_or(|p| p == *k))
            .map(|(_, &timing)| play(&take, timing))
            .collect();
        for played in &plays {
            println!("{}", played.timeline());
            println!("{}", played.row());
        }
        takes.push(plays);
    }
    play::report(&takes);
    for plays in takes.iter().filter(|_| configured) {
        let median = play::Takes(plays).median_success();
        let name = plays[0].name;
        let floor = FLOORS.iter().find(|(n, _)| *n == name).map_or(0.0, |(_, f)| *f);
        assert!(
            median >= floor,
            "{name}: median success {median:.2} below its floor {floor}"
        );
    }
    takes.iter().for_each(|plays| play::assert_promises(plays));
    if configured && only.is_none() {
        let wrong: usize = takes.iter().flatten().map(|p| p.wrong()).sum();
        assert!(
            wrong <= WRONG_CEILING,
            "{wrong} wrong tracking poses, more than {WRONG_CEILING}"
        );
    }
}

/// A ceiling on the `tracking` poses more than 50 mm or 20° off over the crossed takes
/// ([`crossed_takes`]): 0 since the acquisition's quick pass (2026-12-07), 2 on
/// 2026-12-06 (`sweep` with the bowl on the brushes), plus a margin; 17 before a pose
/// that drifted while lost needed the eyes' agreement to be `tracking` on colour (15 on
/// `occlude` with the cup on the brushes), 38 before a doubt
/// needed the verdict's texture bar to end (21 on `yuyv` with the rocket on the boats).
/// A guard against regressions; the target is 0.
const CROSSED_WRONG_CEILING: usize = 4;

/// Each take played with another take's card in front of a third one's wall: the card
/// of the take `k` places on and the wall `2k` places on in [`Scenario::all`], k = 1–6,
/// so 42 plays of card, wall and motion that nobody tuned for, at the middle timing
/// (0.6 / 0.1 s). The seven takes were worked on; these check how much of that carries
/// over. Prints each play's row and the totals; asserts that no play has a `tracking`
/// pose while the card is out of view and the ceiling on wrong poses
/// ([`CROSSED_WRONG_CEILING`]).
#[test]
#[ignore = "about 8 minutes; CI runs it (see .ci/run)"]
fn crossed_takes() {
    let n = Scenario::all().len();
    let name = |path: &str| path.rsplit('/').next().unwrap_or(path).to_string();
    let mut plays = Vec::new();
    println!("\n| k | take | card | wall | success | tracking > 50 mm or 20° off | back after leaving |\n|---|---|---|---|---|---|---|");
    for k in 1..n {
        for i in 0..n {
            let take = crossed(i, k);
            let played = play(&take, play::TIMINGS[1]);
            println!(
                "| {k} | {} | {} | {} | {:.0} % | {} | {} |",
                take.name,
                name(take.card.photo),
                name(take.wall),
                100.0 * played.success(),
                played.wrong(),
                played.back()
            );
            plays.push(played);
        }
    }
    let wrong: usize = plays.iter().map(play::Played::wrong).sum();
    println!(
        "crossed takes: {} plays, median success {:.0} %, {} at 95 % or more; {} with wrong `tracking` poses, {wrong} such poses",
        plays.len(),
        100.0 * play::Takes(&plays).median_success(),
        plays.iter().filter(|p| p.success() >= 0.95).count(),
        plays.iter().filter(|p| p.wrong() > 0).count()
    );
    play::assert_promises(&plays);
    assert!(
        wrong <= CROSSED_WRONG_CEILING,
        "{wrong} wrong tracking poses in the crossed takes, more than {CROSSED_WRONG_CEILING}"
    );
}

/// Take `i` of [`Scenario::all`] with the card of the take `k` places on and the wall
/// `2k` places on.
fn crossed(i: usize, k: usize) -> Scenario {
    let takes = Scenario::all();
    let n = takes.len();
    Scenario {
        card: takes[(i + k) % n].card,
        wall: takes[(i + 2 * k) % n].wall,
        ..takes[i].clone()
    }
}

/// `yuyv`'s motion with the rocket card on the boats' blue water (`crossed_takes`, k =
/// 5): the photo's dark blue edges show little there. The second acquisition, 19 % off
/// in size and 35° off, is rejected by the verdict but shows the photo's pattern
/// (structure 0.85), so it is followed in doubt. No frame is `tracking` more than 50 mm
/// or 20° off (measured on 2026-12-05: the doubt ends at 2.67 s, where the texture terms
/// on every model point vouch for the pose; from there 29 frames are `tracking` within
/// 6 mm and 19° but 31–36 % short, so the take's success is 0 %). Before, the doubt
/// ended at stereo 0.7 and structure 0.75, on the second frame after the acquisition,
/// and 21 `tracking` poses were 20–40° off.
#[test]
fn a_doubted_card_on_a_wall_of_its_colour_is_not_tracking_turned_away() {
    let scene = ("tests/data/photos/rocket.jpg", "tests/data/backgrounds/boats.jpg");
    let played = play_crossed("yuyv", 5, scene);
    assert_eq!(played.wrong(), 0, "tracking poses more than 50 mm or 20° off");
}

/// `occlude`'s motion with the cup card on the brushes (`crossed_takes`, k = 6). The
/// forearm hides 70 % of the card, which is lost at 1.73 s; meanwhile the pose drifts
/// with nothing to hold it. No frame is `tracking` more than 50 mm or 20° off (measured
/// on 2026-12-06: none, success 68 %). Before a drifted pose needed its eyes to agree on
/// every point to be `tracking` on colour, 15 frames from 2.00 s were, 20–26 mm and
/// 26–35° off, on `F_L + F_R` alone (success 65 %).
#[test]
fn a_pose_that_drifted_behind_an_occluder_is_not_tracking_on_colour_alone() {
    let scene = ("tests/data/photos/coffee.jpg", "tests/data/backgrounds/brushes.jpg");
    let played = play_crossed("occlude", 6, scene);
    assert_eq!(played.wrong(), 0, "tracking poses more than 50 mm or 20° off");
}

/// The take `name` crossed `k` places on ([`crossed`]), which must show `scene` (the
/// card's photo and the wall), played at the middle timing; prints its timeline.
fn play_crossed(name: &str, k: usize, scene: (&str, &str)) -> play::Played {
    let i = Scenario::all().iter().position(|t| t.name == name).unwrap();
    let take = crossed(i, k);
    assert_eq!((take.card.photo, take.wall), scene);
    let played = play(&take, play::TIMINGS[1]);
    println!("{}", played.timeline());
    played
}

/// A take with the built-in configuration and the tests' hand–eye transform, frame by
/// frame, and a fresh tracker of its card.
struct Take {
    take: Scenario,
    film: Film,
    model: photopose::estimator::model::PhotoModel,
}

impl Take {
    fn new(name: &str) -> (Self, StreamTracker) {
        let take = Scenario::named(name).unwrap();
        let mut config = photopose::config::Config::load(None).unwrap();
        config.left_from_hand = crate::scenes::hand_eye();
        let root = crate::common::repo("");
        let film = Film::new(&take, &root, &config).unwrap();
        let model = Film::model(&take, &root, &config).unwrap();
        let tracker = StreamTracker::new(model.clone(), config);
        (Self { take, film, model }, tracker)
    }

    /// Frame `i` tracked: the pose's errors (mm, relative size, degrees) and status.
    fn step(&mut self, tracker: &mut StreamTracker, i: usize) -> ([f64; 3], TrackState) {
        let (errors, est) = self.estimate(tracker, i);
        (errors, est.state)
    }

    /// Steps from frame `first` until a frame is `tracking`, following on after each
    /// (as the estimator process tracks through the frames kept during a search), at
    /// most [`ACQUIRED_WITHIN`] frames; the frame that was. An acquisition may end at a
    /// quick pass the verdict did not find (followed in doubt, or rejected and searched
    /// on the next frame).
    fn tracking_from(&mut self, tracker: &mut StreamTracker, first: usize) -> usize {
        for i in first..first + ACQUIRED_WITHIN {
            let (errors, state) = self.step(tracker, i);
            println!("frame {i}: {errors:.1?}, {state:?}");
            tracker.follow_on();
            if state == TrackState::Tracking {
                return i;
            }
        }
        panic!(
            "{}: not tracking within {ACQUIRED_WITHIN} frames of {first}",
            self.take.name
        );
    }

    /// Frame `i` tracked: the pose's errors (mm, relative size, degrees) and the estimate.
    fn estimate(&mut self, tracker: &mut StreamTracker, i: usize) -> ([f64; 3], Estimate) {
        let (judged, est) = self.judged(tracker, i);
        (judged.errors, est)
    }

    /// Frame `i` tracked: the pose judged against the truth, and the estimate.
    fn judged(&mut self, tracker: &mut StreamTracker, i: usize) -> (Judged, Estimate) {
        let bytes = self.film.frame(i);
        let est = play::step(tracker, self.film.rig(), &bytes, self.take.yuyv);
        let size = est.best.size_mm(self.model.l_p, self.model.b_p);
        let tracking = est.state == TrackState::Tracking;
        (self.film.judge(i, &est.best.hand_from_model(), size, tracking), est)
    }
}

/// Frames [`Take::tracking_from`] steps at most.
const ACQUIRED_WITHIN: usize = 8;

/// An acquisition ends at its quick pass (`src/estimator/ga/quick.rs`, 0 generations)
/// where the verdict finds that pass's result, and also where the result's size is
/// settled (`quick::size_settled`) and the last acquisition did not end at a quick pass
/// the verdict did not find; otherwise the search runs from the same scan.
/// - `light`'s first frame (the cup on the creek, moving slowly): found, `tracking`
///   within 20 mm, 10 % and 10° (measured 0.8 mm, 1.4 %, 1.5°).
/// - `sweep`'s first frame (the rocket at 600 mm/s, blurred): not found, but right
///   (2.3 mm, 8.0 %, 4.9°) and followed in doubt, not acquired afresh. The search took
///   another 0.3 s and ended 4.2 mm, 10.6 % and 11.9° off.
/// - `sweep-60fps`' first frame (the bowl on the red marigolds): not found, and
///   rejected (538 mm off); on the next acquisition (frame 15) the search runs.
#[test]
fn an_acquisition_ends_at_its_quick_pass_unless_the_last_one_did_unfound() {
    first_frame("light", TrackState::Tracking);
    let mut tracker = first_frame("sweep", TrackState::Searching);
    tracker.follow_on();
    assert!(!tracker.will_acquire(), "sweep: followed in doubt");

    let (mut red, mut tracker) = Take::new("sweep-60fps");
    let (_, est) = red.estimate(&mut tracker, 0);
    assert_eq!((est.generations, est.state), (0, TrackState::Searching), "sweep-60fps");
    tracker.follow_on();
    assert!(tracker.will_acquire(), "sweep-60fps: rejected, acquired afresh");
    let (_, est) = red.estimate(&mut tracker, 15);
    let searched = photopose::config::Config::load(None)
        .unwrap()
        .tracking
        .acquire_generations;
    assert_eq!(
        est.generations as usize, searched,
        "sweep-60fps frame 15: the search run"
    );
}

/// `take`'s first frame: acquired by its quick pass (0 generations) within the takes'
/// [`GOOD`] bounds (20 mm, 10 %, 10°), with status `state`; the tracker after it.
fn first_frame(name: &str, state: TrackState) -> StreamTracker {
    let (mut take, mut tracker) = Take::new(name);
    let ([mm, size, deg], est) = take.estimate(&mut tracker, 0);
    println!(
        "{name}: {mm:.1} mm, {:.1} %, {deg:.1}°, {} generations, {:?}",
        size * 100.0,
        est.generations,
        est.state
    );
    assert_eq!((est.generations, est.state), (0, state), "{name}");
    assert!(
        [mm, size, deg].iter().zip(GOOD).all(|(e, g)| *e <= g),
        "{name}: {mm:.1} mm, {deg:.1}° off"
    );
    tracker
}

/// The estimator process's catch-up, on `sweep` (600 mm/s, blur): a card acquired on
/// the frame at 0.5 s is followed through the 15 frames that arrived during the
/// acquisition's 0.5 s, each within 10 mm and 15° (measured: 0.9–5.1 mm; the tilt drifts
/// from 1.6° to 11.6° under the blur), and is `tracking` at the end. Before
/// the frames were kept, the next frame the tracker saw was the one at 1.0 s, 300 mm
/// further, and the card was lost there.
#[test]
fn an_acquired_card_is_followed_through_the_frames_kept_during_its_search() {
    let (mut sweep, mut tracker) = Take::new("sweep");
    assert!(tracker.will_acquire());
    let (acquired, state) = sweep.step(&mut tracker, 15);
    assert_eq!(state, TrackState::Tracking, "acquisition {acquired:?}");
    tracker.follow_on();
    for i in 16..=30 {
        assert!(
            !tracker.will_acquire(),
            "frame {i}: no whole-frame search while following"
        );
        let ([mm, _, deg], state) = sweep.step(&mut tracker, i);
        println!("frame {i}: {mm:.1} mm, {deg:.1}°, {state:?}");
        assert!(mm < 10.0 && deg < 15.0, "frame {i}: {mm:.1} mm, {deg:.1}° off");
        if i == 30 {
            assert_eq!(state, TrackState::Tracking);
        }
    }
}

/// A card acquired at its fastest, on `sweep`'s first frame (600 mm/s, about 10 px of
/// blur), where the verdict cannot confirm the pose: the acquisition (its quick pass,
/// 2.3 mm, 8.0 %, 4.9° off) is followed in doubt through the next frames instead of
/// searched afresh. No frame is `tracking` more than 50 mm or 20° off (measured:
/// `searching` on frames 1–6, up to 24° off on frame 1; `tracking` from frame 7, where
/// the texture terms vouch for it), and from frame 12 (0.4 s) every frame is `tracking`
/// within 10 mm, 10 % and 12° (measured up to 30: 3.4 mm, 9.0 %, 10.6° on frame 27;
/// within 10° to frame 30 when the acquisition was the search's, 4.2 mm, 10.6 %, 11.9°
/// off, before 2026-12-07). Before 2026-12-05, this acquisition was searched afresh and
/// nothing was `tracking` until a second one was confirmed.
#[test]
fn a_blurred_acquisition_is_followed_in_doubt_until_its_texture_vouches() {
    let (mut sweep, mut tracker) = Take::new("sweep");
    let (acquired, state) = sweep.step(&mut tracker, 0);
    println!("acquisition: {acquired:.1?}, {state:?}");
    assert_ne!(state, TrackState::Tracking, "a blurred card the verdict cannot confirm");
    tracker.follow_on();
    assert!(!tracker.will_acquire(), "followed in doubt, not searched afresh");
    for i in 1..=30 {
        let ([mm, size, deg], state) = sweep.step(&mut tracker, i);
        println!("frame {i}: {mm:.1} mm, {:.1} %, {deg:.1}°, {state:?}", size * 100.0);
        let tracking = state == TrackState::Tracking;
        assert!(
            !tracking || (mm < 50.0 && deg < 20.0),
            "frame {i}: tracking {mm:.1} mm, {deg:.1}° off"
        );
        if i >= 12 {
            assert!(
                tracking && mm < 10.0 && size < 0.1 && deg < 12.0,
                "frame {i}: {state:?}, {mm:.1} mm, {:.1} %, {deg:.1}° off",
                size * 100.0
            );
        }
    }
}

/// The `approach` ends 0.2 m from the hand (the built-in grasp holds the object at
/// 150 mm), nearer than the search space reaches (`[search] z_mm` from 300 mm in the
/// hand frame): the card is acquired inside it and followed beyond (`[tracking] reach`).
/// Every frame beyond it is `tracking` within 20 mm, 10 % and 10° (measured on its 47
/// frames: within 3.2 mm, 7.4 % and 1.3°). Before, the model stopped at the space's
/// edge and the card was lost 0.1 s after crossing it.
#[test]
fn an_approach_is_followed_nearer_the_hand_than_the_search_space_reaches() {
    let (mut approach, mut tracker) = Take::new("approach");
    let near = photopose::config::Config::load(None).unwrap().search.z_mm[0];
    let (acquired, state) = approach.step(&mut tracker, 60);
    assert_eq!(state, TrackState::Tracking, "acquisition {acquired:?}");
    tracker.follow_on();
    let mut beyond = 0;
    for i in 61..approach.take.frames() {
        let ([mm, size, deg], state) = approach.step(&mut tracker, i);
        let z = approach.film.truth(i).hand_from_model.translation.z;
        if z >= near {
            continue;
        }
        beyond += 1;
        println!(
            "frame {i}: {z:.0} mm from the hand, {mm:.1} mm, {:.1} %, {deg:.1}° off, {state:?}",
            size * 100.0
        );
        assert!(
            state == TrackState::Tracking && mm <= 20.0 && size <= 0.1 && deg <= 10.0,
            "frame {i}, {z:.0} mm from the hand: {state:?}, {mm:.1} mm, {:.1} %, {deg:.1}° off",
            size * 100.0
        );
    }
    assert!(beyond >= 40, "only {beyond} frames beyond the search space");
}

/// A grey board slides over the card from one side (`occlude`, 3–5 s, up to about 55 %
/// covered). The card is acquired from 2.6 s (its quick pass, 13.9° off and not found,
/// followed in doubt: `tracking` from the next frame) and followed: while at least 60 %
/// of it is visible, every frame is `tracking` within 10 mm, 10 % and 10°, except that
/// the first frame back above 60 % may still be `searching` with its pose within those
/// bounds (measured: frame 127, 2.4 mm, 3.8 %, 2.0°; `tracking` before the acquisition
/// could end at an unfound quick pass). Held at its size
/// (`[tracking] size_hold`), the model cannot shrink onto the visible part, and the
/// two eyes' agreement is read without the board's edge, which each eye sees at
/// another place (`stereo_trimmed`). Before, the model shrank 11–26 % and the frames
/// from 65 % visible on were `searching`.
#[test]
fn a_card_partly_under_a_board_is_tracked_at_its_size() {
    let (mut occlude, mut tracker) = Take::new("occlude");
    let tracked = occlude.tracking_from(&mut tracker, 78);
    let (mut covered, mut hidden) = (0, false);
    for i in tracked + 1..occlude.take.frames() {
        let ([mm, size, deg], state) = occlude.step(&mut tracker, i);
        let visible = occlude.film.visible(i);
        if visible < 0.6 {
            hidden = true;
            continue;
        }
        // The first frame back above 60 % may still be `searching`, its pose right.
        let lagging = std::mem::replace(&mut hidden, false) && state == TrackState::Searching;
        covered += (visible < 0.9) as usize;
        println!(
            "frame {i}: {:.0} % visible, {mm:.1} mm, {:.1} %, {deg:.1}° off, {state:?}",
            visible * 100.0,
            size * 100.0
        );
        assert!(
            (state == TrackState::Tracking || lagging) && mm <= 10.0 && size <= 0.1 && deg <= 10.0,
            "frame {i}, {:.0} % visible: {state:?}, {mm:.1} mm, {:.1} %, {deg:.1}° off",
            visible * 100.0,
            size * 100.0
        );
    }
    assert!(covered >= 20, "only {covered} frames partly covered");
}

/// `leave`: the card, tracked until it leaves the view at 2.0 s, comes back in at the
/// left border, which the right camera sees later: at 4.2 s (frame 126) the left camera
/// sees all of it and the right one 71 %. Searched for on every frame from 4.0 s (each a
/// recovery from its last tracked pose), it is `tracking` by frame 127 within 20 mm,
/// 10 % and 10° (measured: frame 126, 1.3 mm, 2.0 %, 2.2°). The recoveries judge the
/// card by the part each eye shows; when the part the right camera did not show counted
/// as mismatches (and 8 recoveries ran before an acquisition), the recoveries of frames
/// 126 and 127 came out 13–16 % short and the first `tracking` frame was 129, although
/// the one of frame 128 was right (1.5 mm, 0.8 %, 1.1°, not found).
#[test]
fn a_card_back_in_view_at_the_border_is_recovered_while_one_camera_sees_part_of_it() {
    let (mut leave, mut tracker) = Take::new("leave");
    let first = leave.tracking_from(&mut tracker, 0);
    // Followed until it leaves, then searched for on every frame while it is away.
    for i in first + 1..BACK - 30 {
        leave.step(&mut tracker, i);
    }
    let tracked = (BACK - 6..=BACK + 1).find_map(|i| {
        let (judged, est) = leave.judged(&mut tracker, i);
        println!(
            "frame {i}: {:?}, {:.3?}, {:?}",
            judged.in_view, judged.errors, est.state
        );
        judged.tracking.then_some((i, judged))
    });
    let (i, judged) = tracked.expect("not tracking by frame 127 (4.23 s)");
    assert!(judged.good(), "frame {i}: {:.3?}", judged.errors);
}

/// The frame of `leave` at 4.2 s.
const BACK: usize = 126;
