//! Scenarios: takes of a robot cell for the synthetic camera. A card photo moves in
//! front of a real photograph (fast sweeps with motion blur, changing light, occluders
//! crossing, leaving the view and coming back, an approach), filmed by the example
//! ZED 2i at HD. [`film`] renders them; `photopose render --scenario` writes one as a
//! recorded sequence, `photopose demo --scenario` plays one through the service, and the
//! tracking-sequence tests play each through the stream tracker.
//!
//! Every take is scored as the held-out sequences are: [`Judged`].

pub mod film;
mod motion;

use nalgebra::Isometry3;

use crate::render::Occluder;

/// A card photo and the box of the object in it (`x, y, w, h`, photo pixels).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CardPhoto {
    /// The photo, relative to the repository's root.
    pub photo: &'static str,
    /// The object's box in the photo.
    pub bbox: [u32; 4],
}

/// One take.
#[derive(Clone)]
pub struct Scenario {
    /// Its name: what happens.
    pub name: &'static str,
    /// The card.
    pub card: CardPhoto,
    /// The wall photo, relative to the repository's root.
    pub wall: &'static str,
    /// The card's length, mm (its breadth by the box's aspect).
    pub length_mm: f64,
    /// Frames per second.
    pub fps: f64,
    /// The take's length, s.
    pub seconds: f64,
    /// Exposure time, s: the card is rendered at sub-frame times across it and averaged
    /// (motion blur). 0: a sharp frame.
    pub exposure_s: f64,
    /// The card at time t: `left_from_model` (mm).
    pub motion: fn(f64) -> Isometry3<f64>,
    /// Per-channel gains `[r, g, b]` on the frame at time t (exposure and white balance).
    pub light: fn(f64) -> [f64; 3],
    /// What stands in front of the card at time t, given the card's pose and size.
    pub occluder: fn(f64, &Isometry3<f64>, [f64; 2]) -> Option<Occluder>,
    /// Gaussian pixel noise, grey levels.
    pub noise: f64,
    /// The frames are sent as YUYV, as the ZED sends them.
    pub yuyv: bool,
    /// The tests play it through a non-identity hand–eye transform (the demo and
    /// `render --scenario` use the configuration's).
    pub hand_eye: bool,
}

impl Scenario {
    /// Every take.
    pub fn all() -> Vec<Scenario> {
        motion::takes()
    }

    /// The take called `name`; the error lists the names.
    pub fn named(name: &str) -> Result<Scenario, String> {
        Self::all().into_iter().find(|s| s.name == name).ok_or_else(|| {
            let names: Vec<&str> = Self::all().iter().map(|s| s.name).collect();
            format!("unknown scenario {name:?}: use one of {}", names.join(", "))
        })
    }

    /// The card's size `[L, B]`, mm: its length and the box's aspect.
    pub fn size_mm(&self) -> [f64; 2] {
        let [_, _, w, h] = self.card.bbox;
        [self.length_mm, self.length_mm * h as f64 / w as f64]
    }

    /// Frames in the take.
    pub fn frames(&self) -> usize {
        (self.seconds * self.fps).round() as usize
    }
}

/// Success: a `tracking` pose within these bounds (mm, relative size, degrees) on a frame
/// with at least [`SCORED_SHARE`] of the card visible.
pub const GOOD: [f64; 3] = [20.0, 0.10, 10.0];
/// The share of the card in view from which a frame is scored.
pub const SCORED_SHARE: f64 = 0.6;
/// A `tracking` pose this far off (mm, degrees) is a wrong one a robot would act on.
pub const WRONG: [f64; 2] = [50.0, 20.0];
/// Below this share of the card in view, the card is out of view.
pub const OUT_OF_VIEW: f64 = 0.1;

/// Shares of the card in view on a frame ([`film::visible_share`]): the left camera's,
/// and both cameras'. A stereo pose and size needs both; a card coming in at the left
/// edge is seen by the left camera first (for 0.5 s in `leave`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InView {
    /// The left camera's share.
    pub left: f64,
    /// Both cameras' share.
    pub both_eyes: f64,
}

/// A pose judged against the truth of its frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Judged {
    /// Shares of the card in view.
    pub in_view: InView,
    /// Whether the pose said `tracking`.
    pub tracking: bool,
    /// Position (mm), worst relative size and rotation (degrees) errors.
    pub errors: [f64; 3],
}

impl Judged {
    /// A frame that got no pose of the card (while a whole-frame search ran).
    pub fn without_pose(in_view: InView) -> Self {
        Self {
            in_view,
            tracking: false,
            errors: [f64::NAN; 3],
        }
    }

    /// Counts towards the success share: enough of the card in view.
    pub fn scored(&self) -> bool {
        self.in_view.left >= SCORED_SHARE
    }

    /// A `tracking` pose within [`GOOD`].
    pub fn good(&self) -> bool {
        self.tracking && self.errors.iter().zip(GOOD).all(|(e, g)| *e <= g)
    }

    /// A `tracking` pose beyond [`WRONG`].
    pub fn wrong(&self) -> bool {
        self.tracking && (self.errors[0] > WRONG[0] || self.errors[2] > WRONG[1])
    }

    /// A `tracking` pose while the card is out of view.
    pub fn tracking_out_of_view(&self) -> bool {
        self.tracking && self.in_view.left < OUT_OF_VIEW
    }
}

/// A return of the card into view: the seconds to the first good pose (infinite: none
/// came) from the first frame on which the left camera sees enough of it to be scored
/// ([`SCORED_SHARE`]), and from the first on which both cameras do (0 where the pose came
/// first).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Return {
    /// Seconds from the left camera's view.
    pub left: f64,
    /// Seconds from both cameras' view.
    pub both_eyes: f64,
}

impl std::fmt::Display for Return {
    /// "0.93 s (0.48 s after both eyes see it)", "0.20 s" where both eyes saw it as
    /// soon as the left one, or "never".
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match (self.left, self.both_eyes) {
            (left, _) if left.is_infinite() => write!(f, "never"),
            (left, both) if both == left => write!(f, "{left:.2} s"),
            (left, both) => write!(f, "{left:.2} s ({both:.2} s after both eyes see it)"),
        }
    }
}

/// Each return into view in `frames` (each frame's time in seconds and its judged pose,
/// in order: the card out of view, then in view enough to be scored).
pub fn reacquisitions(frames: &[(f64, Judged)]) -> Vec<Return> {
    let mut out = Vec::new();
    let mut away = false;
    for (i, (t, judged)) in frames.iter().enumerate() {
        if judged.in_view.left < OUT_OF_VIEW {
            away = true;
        } else if away && judged.scored() {
            away = false;
            let rest = &frames[i..];
            let good = rest.iter().find(|(_, g)| g.good()).map_or(f64::INFINITY, |(s, _)| *s);
            let both = rest
                .iter()
                .find(|(_, g)| g.in_view.both_eyes >= SCORED_SHARE)
                .map_or(good, |(s, _)| *s);
            out.push(Return {
                left: good - t,
                both_eyes: (good - both).max(0.0),
            });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_return_into_view_counts_the_time_to_the_first_good_pose() {
        let frame = |left: f64, both_eyes: f64, tracking: bool, mm: f64| Judged {
            in_view: InView { left, both_eyes },
            tracking,
            errors: [mm, 0.0, 0.0],
        };
        let frames: Vec<(f64, Judged)> = [
            frame(1.0, 1.0, true, 1.0),
            frame(0.0, 0.0, false, 900.0),  // away
            frame(0.4, 0.0, false, 600.0),  // coming back: not scored yet
            frame(0.8, 0.3, false, 500.0),  // back: scored from here
            frame(1.0, 0.6, true, 30.0),    // tracking, but not good; both eyes see it
            frame(1.0, 0.8, true, 2.0),     // good, 0.2 s after coming back
            frame(0.05, 0.0, false, 900.0), // away again
            frame(1.0, 1.0, false, 900.0),  // back, and never found
        ]
        .into_iter()
        .enumerate()
        .map(|(i, j)| (0.1 * i as f64, j))
        .collect();
        let back = reacquisitions(&frames);
        assert_eq!(back.len(), 2);
        assert!((back[0].left - 0.2).abs() < 1e-9, "{back:?}");
        assert!((back[0].both_eyes - 0.1).abs() < 1e-9, "{back:?}");
        assert_eq!(back[0].to_string(), "0.20 s (0.10 s after both eyes see it)");
        assert!(back[1].left.is_infinite());
        assert_eq!(back[1].to_string(), "never");
        let at_once = Return {
            left: 0.3,
            both_eyes: 0.3,
        };
        assert_eq!(at_once.to_string(), "0.30 s");
    }

    #[test]
    fn an_unknown_scenario_names_the_known_ones() {
        assert_eq!(Scenario::named("sweep").map(|s| s.frames()), Ok(120));
        assert_eq!(
            Scenario::named("swoop").err().as_deref(),
            Some("unknown scenario \"swoop\": use one of sweep, sweep-60fps, yuyv, light, occlude, leave, approach")
        );
    }

    #[test]
    fn a_pose_is_judged_by_the_bounds_of_the_held_out_sequences() {
        let judged = |visible, tracking, errors| Judged {
            in_view: InView {
                left: visible,
                both_eyes: visible,
            },
            tracking,
            errors,
        };
        let edge = judged(0.6, true, [20.0, 0.10, 10.0]);
        assert!(edge.scored() && edge.good() && !edge.wrong());
        assert!(!judged(0.59, true, [0.0; 3]).scored());
        assert!(!judged(1.0, true, [20.1, 0.0, 0.0]).good());
        assert!(!judged(1.0, true, [0.0, 0.11, 0.0]).good());
        assert!(!judged(1.0, false, [0.0; 3]).good(), "only a tracking pose counts");
        assert!(judged(1.0, true, [50.1, 0.0, 0.0]).wrong());
        assert!(judged(1.0, true, [0.0, 0.0, 20.1]).wrong());
        assert!(
            !judged(1.0, false, [500.0, 0.0, 90.0]).wrong(),
            "a searching pose is never wrong"
        );
        assert!(judged(0.05, true, [0.0; 3]).tracking_out_of_view());
        assert!(!judged(0.05, false, [0.0; 3]).tracking_out_of_view());
    }
}
