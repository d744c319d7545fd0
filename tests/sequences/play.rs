//! Playing a take through the stream tracker, frame by frame, and scoring each pose
//! against the truth.

use std::fmt::Write as _;
use std::time::Instant;

use photopose::camera::StereoRig;
use photopose::capture::scenario::film::Film;
use photopose::capture::scenario::{Judged, Return, Scenario};
use photopose::config::Config;
use photopose::estimator::tracking::{Estimate, StreamTracker, TrackState};
use photopose::vision::lookup::SbsBytes;
use photopose::vision::PixelFormat;

use crate::common::repo;
use crate::scenes;

/// How long a whole-frame search holds the estimator, seconds: a one-shot acquisition,
/// and a relocation or recovery with the frame's reading. Frames that arrive meanwhile
/// are dropped.
#[derive(Debug, Clone, Copy)]
pub struct Timing {
    pub acquisition_s: f64,
    pub whole_frame_s: f64,
}

/// The timings each take is played at. In the processes an acquisition took 0.5–0.8 s
/// and a relocation 0.1–0.23 s (`photopose latency` and `photopose demo --scenario` on
/// 2 cores). Which frames the tracker sees after a search depends on it, and a take's
/// outcome with them: `sweep` scored 48 % at 0.6 / 0.1 s and 1–3 % at the others.
pub const TIMINGS: [Timing; 3] = [
    Timing {
        acquisition_s: 0.5,
        whole_frame_s: 0.15,
    },
    Timing {
        acquisition_s: 0.6,
        whole_frame_s: 0.1,
    },
    Timing {
        acquisition_s: 0.75,
        whole_frame_s: 0.2,
    },
];

/// One frame's outcome.
#[derive(Debug, Clone, Copy)]
pub struct FrameOutcome {
    /// Time, s.
    pub t: f64,
    /// The pose published for this frame (none: dropped during a whole-frame search).
    pub state: Option<TrackState>,
    /// That pose against the truth (errors NaN when dropped).
    pub judged: Judged,
}

/// A played take.
pub struct Played {
    pub name: &'static str,
    pub timing: Timing,
    pub frames: Vec<FrameOutcome>,
    /// Wall time of the tracking steps, ms (whole-frame searches apart).
    pub tracking_ms: Vec<f64>,
}

/// Renders the take frame by frame and runs the stream tracker on it, through the
/// built-in configuration (with the tests' hand–eye transform if the take asks for it),
/// as the estimator process does: a whole-frame search holds the object for
/// `timing`'s time, the frames that arrive meanwhile get no pose of it (the process
/// publishes `searching`) and are kept, and after the search the tracker follows the
/// object through them ([`CATCH_UP_S`] each) before it takes the newest frame.
/// `TRACK_SEED=N` replaces the configuration's seed (the spread over seeds).
pub fn play(take: &Scenario, timing: Timing) -> Played {
    let mut config = Config::load(None).expect("built-in config");
    if take.hand_eye {
        config.left_from_hand = scenes::hand_eye();
    }
    if let Some(seed) = std::env::var("TRACK_SEED").ok().and_then(|s| s.parse().ok()) {
        config.ga.seed = seed;
    }
    let mut film = Film::new(take, &repo(""), &config).expect("the take's photos");
    let model = Film::model(take, &repo(""), &config).expect("the take's model");
    let mut tracker = StreamTracker::new(model.clone(), config.clone());
    let (mut frames, mut tracking_ms) = (Vec::with_capacity(take.frames()), Vec::new());
    let (mut busy_until, mut backlog) = (0.0, Vec::new());
    for i in 0..take.frames() {
        let t = film.time(i);
        if t >= busy_until && !backlog.is_empty() {
            busy_until += CATCH_UP_S * catch_up(&mut tracker, &mut film, &backlog, take.yuyv) as f64;
            backlog.clear();
        }
        let (state, judged) = if t < busy_until {
            backlog.push(i);
            (None, Judged::without_pose(film.in_view(i)))
        } else {
            let whole = tracker.will_acquire();
            let bytes = film.frame(i);
            let start = Instant::now();
            let est = step(&mut tracker, film.rig(), &bytes, take.yuyv);
            let ms = start.elapsed().as_secs_f64() * 1e3;
            if whole {
                busy_until = t + match est.generations as usize {
                    0 => timing.acquisition_s * QUICK_SHARE,
                    g if g == config.tracking.acquire_generations => timing.acquisition_s * FALLBACK,
                    _ => timing.whole_frame_s,
                };
            } else {
                tracking_ms.push(ms);
            }
            let size = est.best.size_mm(model.l_p, model.b_p);
            let tracking = est.state == TrackState::Tracking;
            (
                Some(est.state),
                film.judge(i, &est.best.hand_from_model(), size, tracking),
            )
        };
        frames.push(FrameOutcome { t, state, judged });
    }
    Played {
        name: take.name,
        timing,
        frames,
        tracking_ms,
    }
}

/// An acquisition that its quick pass ends (the whole-frame step's generations 0, the
/// verdict finding its result or not), and one that goes on to the search, as shares
/// of the timing's acquisition. Measured in the tracker on 2 cores: the frame's
/// preparation and scan 140–250 ms, the quick pass 33–34 ms, the search after it about
/// 300 ms; on the first frames of the 49 takes and crossed plays the quick pass took
/// 45–47 % of the search's time, the scan counted in both.
const QUICK_SHARE: f64 = 0.4;
const FALLBACK: f64 = 1.08;

/// How long following the object through one kept frame takes, s: a tracking step
/// (2–5 ms at HD on 2 cores) and the frame's reading.
pub const CATCH_UP_S: f64 = 0.005;

/// Tracks through the frames `kept` during a whole-frame search, as the search's
/// thread does ([`photopose::estimator::objects`]), until they run out or the tracker
/// needs the whole frame again; the frames followed.
fn catch_up(tracker: &mut StreamTracker, film: &mut Film, kept: &[usize], yuyv: bool) -> usize {
    tracker.follow_on();
    let mut followed = 0;
    for &j in kept {
        if tracker.will_acquire() {
            break;
        }
        let bytes = film.frame(j);
        step(tracker, film.rig(), &bytes, yuyv);
        followed += 1;
    }
    followed
}

/// One tracker step on a side-by-side frame's bytes, RGB8 or YUYV.
pub fn step(tracker: &mut StreamTracker, rig: &StereoRig, bytes: &[u8], yuyv: bool) -> Estimate {
    let (width, height) = (rig.width as usize, rig.height as usize);
    let (row_stride, format) = if yuyv {
        (4 * width, PixelFormat::Yuyv)
    } else {
        (6 * width, PixelFormat::Rgb8)
    };
    let frame = SbsBytes {
        bytes,
        width,
        height,
        row_stride,
        format,
    };
    tracker.prepare(&frame).expect("a whole HD frame");
    tracker.step().expect("a prepared frame")
}

/// Per-take figures.
impl Played {
    /// Share of the frames with enough of the card in view that got a good pose.
    pub fn success(&self) -> f64 {
        let scored: Vec<_> = self.frames.iter().filter(|f| f.judged.scored()).collect();
        scored.iter().filter(|f| f.judged.good()).count() as f64 / scored.len().max(1) as f64
    }

    /// `tracking` poses more than 50 mm or 20° off.
    pub fn wrong(&self) -> usize {
        self.frames.iter().filter(|f| f.judged.wrong()).count()
    }

    /// `tracking` poses while the card is out of view.
    pub fn tracking_out_of_view(&self) -> usize {
        self.frames.iter().filter(|f| f.judged.tracking_out_of_view()).count()
    }

    /// For each return into view (out of view, then scored again), the seconds until the
    /// first good pose (infinite: never), from when the left eye and both eyes see it.
    pub fn reacquisitions(&self) -> Vec<Return> {
        let frames: Vec<(f64, Judged)> = self.frames.iter().map(|f| (f.t, f.judged)).collect();
        photopose::capture::scenario::reacquisitions(&frames)
    }

    /// The time to the first good pose, s.
    pub fn first_good(&self) -> f64 {
        self.frames
            .iter()
            .find(|f| f.judged.good())
            .map_or(f64::INFINITY, |f| f.t)
    }

    /// The seconds back after each return into view, as the tables print them ("–" for
    /// none).
    pub fn back(&self) -> String {
        let back: Vec<String> = self.reacquisitions().iter().map(Return::to_string).collect();
        if back.is_empty() {
            "–".to_string()
        } else {
            back.join(", ")
        }
    }

    /// The table's row.
    pub fn row(&self) -> String {
        let mut ms = self.tracking_ms.clone();
        ms.sort_by(f64::total_cmp);
        let p99 = ms
            .get(((ms.len() as f64 * 0.99) as usize).min(ms.len().saturating_sub(1)))
            .copied();
        format!(
            "| {} | {} / {} s | {:.0} % | {} | {} | {:.2} s | {} | {:.1} ms |",
            self.name,
            self.timing.acquisition_s,
            self.timing.whole_frame_s,
            100.0 * self.success(),
            self.wrong(),
            self.tracking_out_of_view(),
            self.first_good(),
            self.back(),
            p99.unwrap_or(f64::NAN)
        )
    }

    /// One line per frame: time, visible share, status and errors.
    pub fn timeline(&self) -> String {
        let mut s = format!(
            "{} ({} / {} s):\n",
            self.name, self.timing.acquisition_s, self.timing.whole_frame_s
        );
        for f in &self.frames {
            let state = match f.state {
                None => "-",
                Some(TrackState::Tracking) => "T",
                Some(TrackState::Searching) => "s",
                Some(TrackState::Lost) => "l",
            };
            let [p, z, r] = f.judged.errors;
            let _ = writeln!(
                s,
                "  {:5.2} {:3.0}% {state} {p:6.1} mm {:5.1} % {r:5.1}°",
                f.t,
                100.0 * f.judged.in_view.left,
                100.0 * z
            );
        }
        s
    }
}

/// The header of the table of every play.
const HEADER: &str = "| take | acquisition / relocation | success | tracking > 50 mm or 20° off | tracking out of view | first good pose | back after leaving | tracking step p99 |\n|---|---|---|---|---|---|---|---|";

/// The header of the table per take, over its timings.
const SUMMARY_HEADER: &str = "| take | success (lowest, median, highest) | tracking > 50 mm or 20° off (all timings) | tracking out of view | back after leaving (slowest) |\n|---|---|---|---|---|";

/// Targets per take: success share, and seconds to a good pose after coming back.
const TARGET_SUCCESS: f64 = 0.95;
const TARGET_BACK_S: f64 = 0.5;

/// A take's plays at every timing.
pub struct Takes<'a>(pub &'a [Played]);

impl Takes<'_> {
    /// The median success share over the timings.
    pub fn median_success(&self) -> f64 {
        let mut s: Vec<f64> = self.0.iter().map(Played::success).collect();
        s.sort_by(f64::total_cmp);
        s.get(s.len() / 2).copied().unwrap_or(0.0)
    }

    /// The summary row.
    fn row(&self) -> String {
        let mut s: Vec<f64> = self.0.iter().map(Played::success).collect();
        s.sort_by(f64::total_cmp);
        let pct = |k: usize| s.get(k).map_or(f64::NAN, |v| 100.0 * v);
        let back = (self.0.iter().flat_map(Played::reacquisitions)).max_by(|a, b| a.left.total_cmp(&b.left));
        format!(
            "| {} | {:.0} %, {:.0} %, {:.0} % | {} | {} | {} |",
            self.0.first().map_or("", |p| p.name),
            pct(0),
            pct(s.len() / 2),
            pct(s.len().saturating_sub(1)),
            self.0.iter().map(Played::wrong).sum::<usize>(),
            self.0.iter().map(Played::tracking_out_of_view).sum::<usize>(),
            back.map_or("–".to_string(), |b| b.to_string())
        )
    }

    /// Whether the take reaches the targets at every timing.
    fn reached(&self) -> bool {
        self.0.iter().all(|p| {
            p.success() >= TARGET_SUCCESS
                && p.wrong() == 0
                && p.reacquisitions().iter().all(|r| r.left <= TARGET_BACK_S)
        })
    }
}

/// Prints the table of every play, the table per take and the targets (reached or NOT
/// reached), and writes both tables to `target/sequences/sequences.md`.
pub fn report(takes: &[Vec<Played>]) {
    let plays: Vec<String> = takes.iter().flatten().map(Played::row).collect();
    let summary: Vec<String> = takes.iter().map(|t| Takes(t).row()).collect();
    let text = format!(
        "{HEADER}\n{}\n\n{SUMMARY_HEADER}\n{}\n",
        plays.join("\n"),
        summary.join("\n")
    );
    println!("{text}");
    for t in takes {
        let name = t.first().map_or("", |p| p.name);
        println!(
            "target {name}: success ≥ 95 %, no tracking pose > 50 mm or 20° off, back within 0.5 s, at every timing: {}",
            if Takes(t).reached() { "reached" } else { "NOT reached" }
        );
    }
    let dir = crate::common::repo("target/sequences");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("sequences.md"), text).unwrap();
}

/// The promise every take keeps: no `tracking` pose while the card is out of view.
pub fn assert_promises(rows: &[Played]) {
    for p in rows {
        assert_eq!(
            p.tracking_out_of_view(),
            0,
            "{} ({} / {} s): tracking while the card is out of view",
            p.name,
            p.timing.acquisition_s,
            p.timing.whole_frame_s
        );
    }
}
