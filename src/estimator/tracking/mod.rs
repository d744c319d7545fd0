//! Tracking across frames, as in the authors' real-time multi-step GA: the population
//! of the previous frame is moved by the predicted motion, re-scored on the new frame
//! and evolved for a few generations; the best individual is the frame's pose. When
//! the fitness stays low the search widens (immigrants), and after a while the object
//! is acquired afresh with the one-shot robust search. An acquisition's frame is about a
//! second old when its search ends: the estimator process keeps the frames that arrived
//! meanwhile and tracks through them ([`Tracker::follow_on`]); a caller that did not
//! keep them has the next frame relocate the acquired model ([`relocate`]) first.

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use crate::config::Config;
use crate::estimator::fitness::Fitness;
use crate::estimator::ga::live::{Breeding, EdgeMoves, LivePopulation};
use crate::estimator::ga::scan::Scanned;
use crate::estimator::ga::{compass, relocate, Bounds, Genes, Problem, GENES};
use crate::estimator::pose::PoseSize;
use crate::estimator::settings::{GaSettings, RobustSettings, TrackingSettings};
use crate::estimator::verify::{self, texture::Texture};

mod stream;

pub use stream::{search_windows, FrameError, StreamTracker};

/// The result for one frame.
#[derive(Debug, Clone, Copy)]
pub struct Estimate {
    /// The frame's pose and size: the best individual.
    pub best: PoseSize,
    /// Fitness of `best` at full resolution.
    pub fitness: Fitness,
    /// Generations run on this frame.
    pub generations: u32,
    /// How far the pose can be trusted.
    pub state: TrackState,
}

/// How far a frame's pose can be trusted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TrackState {
    /// The object is tracked; the pose is current.
    Tracking,
    /// The fitness is low, (re)acquiring, or the tilt is not resolved: the pose is the
    /// best guess so far.
    Searching,
    /// Nothing matches; the pose must not be acted on.
    Lost,
}

impl TrackState {
    /// This status with `tracking` lowered to `searching`.
    pub fn not_tracking(self) -> Self {
        match self {
            TrackState::Tracking => TrackState::Searching,
            other => other,
        }
    }
}

/// Share of each generation's children also rescaled about one of their edges
/// ([`EdgeMoves`]), and the spread of that rescaling (log of the factor): a model that
/// shrank onto part of a target that moved further than predicted grows back.
const EDGE_MOVES: f64 = 0.25;
const EDGE_STEP: f64 = 0.03;

/// Share of the difference between a frame's displacement and the predicted one that
/// the position's velocity estimate takes on (and the share of the last change that the
/// other genes are predicted to repeat).
const VELOCITY_GAIN: f64 = 0.5;

/// Evaluations of the compass climb of each tracking frame's best individual, and the
/// step (degrees) and the most steps in a row of the turns tried before it
/// ([`Tracker::climb_best`]): about a third of a tracking frame's evaluations.
const CLIMB_EVALUATIONS: usize = 60;
const TURN_STEP_DEG: f64 = 4.0;
const TURNS: usize = 4;

/// Generations of the tracking GA after a relocation, on the whole frame at full
/// resolution: the orientation and size that changed during the acquisition settle.
pub const RELOCATE_GENERATIONS: usize = 12;

/// Share of the acquisition's `F_L + F_R` a frame needs to be `tracking` after a relocation the
/// verdict did not call found. A model nearer and smaller than the object (or farther
/// and larger) matches the left image as well; only the stereo term tells them apart,
/// and 30 mm off in depth it still scores 0.88 of the truth.
const DOUBT_SHARE: f64 = 0.95;

/// The least stereo term on every point at which `F_L + F_R` calls a pose `tracking`
/// again after a frame below `lost_fitness` (until a `tracking` frame or a whole-frame
/// search): while the card was hidden, the pose drifted with nothing to hold it. With
/// the cup card on a wall of brushes (`crossed_takes`), the forearm hid 70 % of the card;
/// as it withdrew, the drifted pose, 20–26 mm and 26–35° off, regained the share of the
/// best `F_L + F_R` on colour alone while its eyes agreed at 0.42–0.62, and 15 frames
/// were called `tracking` so. The right pose read 0.95 when it was found again; where
/// the verdict's stereo ramp starts, this bar changed none of the seven takes.
const DRIFT_STEREO: f64 = 0.7;

/// Whether the two eyes agree at a pose as the verdict asks ([`verify::stereo_holds`]) on
/// every point of `texture`, or on all but those where they disagree far more than at
/// most (`stereo_trimmed`): an occluder's edge, seen at another place by each eye. Under
/// a board over 30–55 % of the card, the held pose read 0.72–0.86 on every point.
/// The photo's pattern must show there too (a structure term of at least
/// [`EYES_STRUCTURE`]): the eyes agree on whatever lies at the pose.
fn eyes_agree(texture: &Texture, stereo_trimmed: impl FnOnce() -> f64) -> bool {
    texture.structure >= EYES_STRUCTURE
        && (verify::stereo_holds(texture)
            || verify::stereo_holds(&Texture {
                stereo: stereo_trimmed(),
                ..*texture
            }))
}

/// The least structure term at which the two eyes' agreement keeps a pose tracked
/// ([`eyes_agree`]). They agree as well on the card turned half round, or on a patch of
/// the wall. On the looped `yuyv` take (`photopose demo`) runs had up to 76 `tracking`
/// poses 140–175° off in 20 s so, with structure −0.02–0.36 and `F_L + F_R` 1.0–1.4.
/// A blurred card read 0.6 or more.
const EYES_STRUCTURE: f64 = 0.5;

/// Share of the way a `tracking` frame's size moves the size held on tracking frames
/// (`[tracking] size_hold`): a rigid object's size does not change, and a few frames'
/// estimates average out its jitter.
const SIZE_GAIN: f64 = 0.1;

/// Relocations of the last tracked pose tried after the object was lost, before the next
/// acquisition (each reads and searches the whole frame: 0.1–0.2 s at HD in the play,
/// about 65 ms in the processes). An object that comes back into view as it left is
/// found again by the first of them; one that comes back from the other side, once both
/// eyes see most of it. With 8 they ran out while the `leave` take's card was away
/// (1.5 s), and an acquisition, which cannot reach the card beyond the search space,
/// held the frames as it came back (0.93 s after the left camera saw it; 0.57 s with
/// 12). 16 cost 18 points on a take whose last tracked pose was wrong (`crossed_takes`,
/// `sweep-60fps` k = 6), 12 one.
pub const RECOVERIES: usize = 12;

/// What the tracker does with the next frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Plan {
    /// The one-shot robust search over the whole frame.
    Acquire,
    /// Relocate the model just acquired on an older frame.
    Relocate,
    /// The object is lost: relocate its last tracked pose.
    Recover,
    /// Track the population around the predicted pose.
    Track,
}

/// How a whole-frame step is judged ([`Tracker::step_whole`]).
#[derive(Clone, Copy)]
pub struct Judges<'a> {
    /// The `F_L + F_R` that tracking frames would give the best genes (they read fewer
    /// points, which for a finely textured photo scores lower than the whole model):
    /// the status is judged on it, and the tracking frames that follow compare theirs
    /// with it.
    pub tracking_f: &'a dyn Fn(&Genes) -> f64,
    /// Whether the verdict finds a pose: an acquisition's quick pass ends the
    /// acquisition where it does.
    pub found: &'a dyn Fn(&PoseSize) -> bool,
}

/// A GA population that lives from frame to frame.
pub struct Tracker {
    settings: TrackingSettings,
    /// The photo box `[L_P, B_P]`, pixels.
    box_px: [f64; 2],
    ga: GaSettings,
    robust: RobustSettings,
    pop: LivePopulation,
    rng: StdRng,
    /// Frames in a row not tracked (below `min_fitness`, or below `min_fitness_share` of
    /// `best_f`).
    searching: usize,
    /// The best `F_L + F_R` since the last acquisition.
    best_f: f64,
    /// Best genes of the last frame and their change per frame (constant velocity).
    last_best: Option<Genes>,
    velocity: Genes,
    frames: u64,
    /// The population was acquired on an older frame: relocate it on the next one.
    relocating: bool,
    /// The last relocation was not judged found: tracking needs [`DOUBT_SHARE`] of the
    /// acquisition's `F_L + F_R` until a frame is tracked.
    doubted: bool,
    /// A frame fell below `lost_fitness` since the last `tracking` one or whole-frame
    /// search: the pose drifted while the card was hidden ([`DRIFT_STEREO`]).
    drifted: bool,
    /// The best genes of the last `tracking` frame.
    anchor: Option<Genes>,
    /// Recoveries left before the next acquisition.
    recoveries: usize,
    /// The genes of the size (α, k) that tracking frames hold the object at.
    held_size: Option<[f64; 2]>,
    /// The last acquisition ended at its quick pass although the verdict did not find
    /// its result (its size settled); the next acquisition runs the search where its
    /// quick pass is not found either, until a frame is confirmed. Where the verdict
    /// cannot confirm a right result (a blurred card), the result is followed in doubt
    /// at once; where it is wrong, the next acquisition starts a search's time sooner.
    unfound_quick: bool,
}

/// What an acquisition's quick pass came to ([`Tracker::acquire`]).
enum Quick {
    /// The verdict finds its result.
    Found(Genes),
    /// The verdict does not find its result, whose size is settled, and the last
    /// acquisition did not end at an unfound quick pass: taken.
    Settled(Genes),
    /// Neither (or no quick pass): the search runs.
    Unfound,
}

impl Tracker {
    /// A tracker of a model whose photo box is `box_px` (`[L_P, B_P]`).
    pub fn new(config: &Config, box_px: [f64; 2], seed: u64) -> Self {
        let n = config.tracking.population;
        Self {
            settings: config.tracking.clone(),
            box_px,
            ga: config.ga.clone(),
            robust: config.robust.clone(),
            pop: LivePopulation::with_capacity(n),
            rng: StdRng::seed_from_u64(seed),
            searching: 0,
            best_f: 0.0,
            last_best: None,
            velocity: [0.0; GENES],
            frames: 0,
            relocating: false,
            doubted: false,
            drifted: false,
            anchor: None,
            recoveries: 0,
            held_size: None,
            unfound_quick: false,
        }
    }

    /// The verdict on the last acquisition was "not found": the next frame is acquired
    /// afresh, and nothing is tracked from this pose.
    pub fn reject_acquisition(&mut self) {
        self.recovery_failed();
        self.relocating = false;
        self.recoveries = RECOVERIES;
    }

    /// The last frame's `tracking` pose is confirmed (a tracking frame, or a whole-frame
    /// search the verdict calls found): the object is recovered from there when lost.
    pub fn confirm(&mut self) {
        self.anchor = self.last_best;
        self.unfound_quick = false;
        self.recoveries = RECOVERIES;
    }

    /// The verdict on the last recovery was "not found": the object is still lost.
    pub fn recovery_failed(&mut self) {
        self.searching = self.searching.max(self.settings.lost_after_frames + 1);
    }

    /// The last frame's pose was not judged found although its fitness may be high: the
    /// next frames search more widely, it takes a tracked frame to say `tracking`, and
    /// the size is not held until a frame's texture vouches for it.
    pub fn doubt(&mut self) {
        self.searching = self.searching.max(1);
        self.doubted = true;
        self.held_size = None;
    }

    /// The next frame directly follows the last one searched (frames kept while a
    /// whole-frame search ran are caught up on): an acquisition is tracked on from
    /// there, not relocated.
    pub fn follow_on(&mut self) {
        self.relocating = false;
    }

    /// What the next frame is for: an acquisition until the first one is found and after
    /// the recoveries of a lost object failed; a relocation after an acquisition.
    pub fn plan(&self) -> Plan {
        let lost = self.searching > self.settings.lost_after_frames;
        if self.pop.is_empty() || (lost && (self.recoveries == 0 || self.anchor.is_none())) {
            Plan::Acquire
        } else if lost {
            Plan::Recover
        } else if self.relocating {
            Plan::Relocate
        } else {
            Plan::Track
        }
    }

    /// Whether the pose is tracked in doubt (after a relocation the verdict did not call
    /// found), until a frame is `tracking`.
    pub fn doubted(&self) -> bool {
        self.doubted
    }

    /// Whether the last frame was `tracking`.
    pub fn is_tracked(&self) -> bool {
        self.searching == 0 && !self.pop.is_empty()
    }

    /// True until the first acquisition, and after a lost object's recoveries failed.
    pub fn needs_acquisition(&self) -> bool {
        self.plan() == Plan::Acquire
    }

    /// The genes expected on the next frame (last best moved by the estimated velocity,
    /// not clamped into the bounds); `None` while the whole frame is to be searched (see
    /// [`Tracker::plan`]).
    pub fn prediction(&self) -> Option<Genes> {
        if self.plan() != Plan::Track {
            return None;
        }
        self.last_best.map(|b| std::array::from_fn(|i| b[i] + self.velocity[i]))
    }

    /// Processes one frame.
    pub fn step(&mut self, problem: &Problem) -> Estimate {
        self.step_judged(problem, None)
    }

    /// [`Tracker::step`] on a whole frame, judged as `judged` says ([`Judges`]).
    pub fn step_whole(&mut self, problem: &Problem, judged: Judges) -> Estimate {
        self.step_judged(problem, Some(judged))
    }

    fn step_judged(&mut self, problem: &Problem, judged: Option<Judges>) -> Estimate {
        self.frames += 1;
        let plan = self.plan();
        let tracking_f = judged.map(|j| j.tracking_f);
        let generations = match plan {
            Plan::Acquire => self.acquire(problem, judged.map(|j| j.found)),
            Plan::Relocate => {
                self.relocate(problem, self.pop.best().map(|b| b.0));
                RELOCATE_GENERATIONS
            }
            Plan::Recover => {
                self.recoveries -= 1;
                self.relocate(problem, self.anchor);
                RELOCATE_GENERATIONS
            }
            Plan::Track => {
                self.track(problem);
                self.settings.generations_per_frame
            }
        };
        let (best, fitness) = self
            .pop
            .best()
            .expect("an acquired population holds at least its best individual");
        if let Some(last) = self.last_best {
            self.velocity = std::array::from_fn(|i| {
                let moved = best[i] - last[i];
                if i < 3 {
                    // Position: an alpha-beta filter. The velocity moves halfway toward
                    // this frame's displacement, so a steady motion is predicted in
                    // full (600 mm/s is 20 mm a frame at 30 fps), one frame's jitter in
                    // half.
                    self.velocity[i] + VELOCITY_GAIN * (moved - self.velocity[i])
                } else {
                    // Orientation and size: half the last change only. What the frame
                    // observes weakly (the tilt of a small card) wanders from frame to
                    // frame; a filter would keep it drifting.
                    VELOCITY_GAIN * moved
                }
            });
        }
        self.last_best = Some(best);
        // A relocation is judged against the acquisition's fitness, which the verdict
        // confirmed: the same object, as well matched.
        let pose = problem.bounds.decode(&best);
        let texture = problem.texture_judged(&pose);
        let state = self.judge(
            tracking_f.map_or(fitness.sum(), |f| f(&best)),
            plan == Plan::Acquire,
            &texture,
            || problem.stereo_trimmed_judged(&pose),
        );
        if state == TrackState::Tracking && plan == Plan::Track {
            self.confirm();
        }
        self.hold_size(&best, plan == Plan::Track, state, verify::texture_vouches(&texture));
        Estimate {
            best: pose,
            fitness,
            generations: generations as u32,
            state,
        }
    }

    /// The status of a frame whose best individual scored `f` (`F_L + F_R`,
    /// [`Fitness::sum`], which an occluder or the wall behind the card seen differently
    /// by each eye does not lower as it lowers `F`; `acquired`: by a fresh acquisition)
    /// and whose texture terms are
    /// `texture` ([`Problem::texture_judged`]), counting the frames in a row that were
    /// not tracked. A pose is tracked
    /// - where its texture vouches for it ([`verify::texture_vouches`]): a card whose
    ///   colours the light changed, whose `f` may be low; or
    /// - where `f` is at least `[tracking] min_fitness` and either its share of the best
    ///   `f` since the acquisition or (not in doubt) the two eyes' agreement holds
    ///   ([`verify::stereo_holds`]): blur lowers the `f` of the right pose, not the two
    ///   eyes' agreement on it. So does something in front of the card; the eyes then
    ///   disagree where it lies, and the agreement is also read without those points
    ///   (`stereo_trimmed`, [`Problem::stereo_trimmed_judged`]). After a frame below
    ///   `lost_fitness`, colour also needs the eyes to agree on every point
    ///   ([`DRIFT_STEREO`]).
    ///
    /// Never below `lost_fitness`.
    fn judge(&mut self, f: f64, acquired: bool, texture: &Texture, stereo_trimmed: impl FnOnce() -> f64) -> TrackState {
        self.best_f = if acquired { f } else { self.best_f.max(f) };
        let share = if self.doubted {
            DOUBT_SHARE
        } else {
            self.settings.min_fitness_share
        };
        let colour = f >= self.settings.min_fitness
            && (!self.drifted || texture.stereo >= DRIFT_STEREO)
            && (f >= share * self.best_f || !self.doubted && eyes_agree(texture, stereo_trimmed));
        let tracked = verify::texture_vouches(texture) || colour;
        self.searching = if tracked { 0 } else { self.searching + 1 };
        self.doubted &= !tracked;
        self.drifted &= !tracked;
        // Below the floor (or NaN) the pose is never called tracked.
        if f.is_nan() || f < self.settings.lost_fitness {
            self.drifted = true;
            TrackState::Lost
        } else if tracked {
            TrackState::Tracking
        } else if self.searching > self.settings.lost_after_frames {
            TrackState::Lost
        } else {
            TrackState::Searching
        }
    }

    /// The size that tracking frames hold: a whole-frame search's (none while it is in
    /// doubt: a blurred acquisition's may be 10 % off), or else the first `tracking`
    /// frame's whose texture vouches for it; then moved [`SIZE_GAIN`] of the way towards
    /// each `tracking` frame's.
    fn hold_size(&mut self, best: &Genes, tracking_frame: bool, state: TrackState, vouched: bool) {
        let size = [best[6], best[7]];
        self.held_size = match self.held_size {
            _ if !tracking_frame => Some(size),
            held if state != TrackState::Tracking => held,
            None => vouched.then_some(size),
            Some(h) => Some(std::array::from_fn(|i| h[i] + SIZE_GAIN * (size[i] - h[i]))),
        };
    }

    /// `bounds` for the next tracking frame: its size genes held within `[tracking]
    /// size_hold` of the held size ([`Bounds::holding_size`]), once one is held.
    pub fn holding(&self, bounds: Bounds) -> Bounds {
        match self.held_size {
            Some(size) if self.settings.size_hold > 0.0 => bounds.holding_size(size, self.settings.size_hold),
            _ => bounds,
        }
    }

    /// The acquisition scan and its quick pass ([`quick`](crate::estimator::ga::quick)),
    /// judged by `found` (the verdict). Its result is taken where `found` takes it, and
    /// also where its size is settled ([`quick::size_settled`]) and the last acquisition
    /// did not end at an unfound quick pass ([`Tracker::unfound_quick`]); otherwise (or
    /// without `found`) the one-shot robust search runs from the same scan. Then a
    /// population around the answer. Returns the generations run (0: the quick pass's
    /// result taken).
    fn acquire(&mut self, problem: &Problem, found: Option<&dyn Fn(&PoseSize) -> bool>) -> usize {
        use crate::estimator::ga::{robust, scan};
        let seed = self.rng.random();
        let scanned = (problem.levels.len() > 1).then(|| scan::seeds(problem, self.ga.population));
        let quick = match (&scanned, found) {
            (Some(s), Some(found)) => self.quick_pass(problem, s, found),
            _ => Quick::Unfound,
        };
        let (best, generations) = match quick {
            Quick::Found(g) | Quick::Settled(g) => (g, 0),
            Quick::Unfound => {
                let generations = self.settings.acquire_generations;
                let outcome = robust::run(problem, &self.ga, &self.robust, generations, seed, &mut |_| {}, scanned);
                (problem.bounds.encode(&outcome.best), generations)
            }
        };
        self.unfound_quick = matches!(quick, Quick::Settled(_));
        let (n, sigma) = (self.settings.population, self.settings.sigma);
        self.pop.seed_around(problem, best, n, sigma, &mut self.rng);
        self.relocating = true;
        self.doubted = false;
        self.drifted = false;
        self.searching = 0;
        self.last_best = None;
        self.velocity = [0.0; GENES];
        generations
    }

    /// The quick pass on `scanned`, judged by `found`; its size is checked only where
    /// its result could be taken unfound (not after an acquisition that was).
    fn quick_pass(&self, problem: &Problem, scanned: &Scanned, found: &dyn Fn(&PoseSize) -> bool) -> Quick {
        use crate::estimator::ga::quick;
        let start = std::time::Instant::now();
        let judged = match quick::quick(problem, scanned) {
            Some((g, _)) if found(&problem.bounds.decode(&g)) => Quick::Found(g),
            Some((g, _)) if !self.unfound_quick && quick::size_settled(problem, &g) => Quick::Settled(g),
            _ => Quick::Unfound,
        };
        let said = match judged {
            Quick::Found(_) => "found",
            Quick::Settled(_) => "not found, its size settled",
            Quick::Unfound => "not found",
        };
        tracing::debug!("quick pass: {said} in {:.0} ms", start.elapsed().as_secs_f64() * 1e3);
        judged
    }

    /// Finds the model at `from` (just acquired, or last tracked) again on this frame
    /// (translated, see [`relocate`](relocate::relocate)), then lets the population
    /// settle around it.
    fn relocate(&mut self, problem: &Problem, from: Option<Genes>) {
        self.relocating = false;
        self.drifted = false;
        let Some(from) = from else {
            return;
        };
        let (moved, _) = relocate::relocate(problem, &problem.bounds.decode(&from), self.box_px);
        let (n, sigma) = (self.settings.population, self.settings.sigma);
        self.pop.seed_around(problem, moved, n, sigma, &mut self.rng);
        self.evolve(problem, RELOCATE_GENERATIONS, false);
        self.last_best = None;
        self.velocity = [0.0; GENES];
    }

    /// Predicts, re-scores and evolves the population on a new frame.
    fn track(&mut self, problem: &Problem) {
        self.pop.shift(problem, &self.velocity);
        self.evolve(problem, self.settings.generations_per_frame, self.searching > 0);
        self.climb_best(problem);
    }

    /// Turns the best individual about its own axes in the card's plane while that
    /// raises its score, then climbs the best ([`compass::climb`]); each result that
    /// scores higher takes the place of the worst individual. The GA's few small
    /// mutations a frame follow a card turning at 60°/s (2° a frame at 30 fps) too
    /// slowly: the tilt lagged 15–20° behind on the sweep, while the fitness at the
    /// truth was higher.
    fn climb_best(&mut self, problem: &Problem) {
        let Some(start) = self.pop.best() else { return };
        // The turns return `start` unless they found better: either way the best now.
        let turned = compass::turn_while_better(problem, 0, start, TURN_STEP_DEG.to_radians(), TURNS);
        if turned.1.score > start.1.score {
            self.pop.inject(turned.0, turned.1);
        }
        let climbed = compass::climb(problem, 0, turned.0, CLIMB_EVALUATIONS);
        if climbed.1.score > turned.1.score {
            self.pop.inject(climbed.0, climbed.1);
        }
    }

    /// Evolves the population `generations` generations; `searching` widens the mutation
    /// and lets immigrants in.
    fn evolve(&mut self, problem: &Problem, generations: usize, searching: bool) {
        let breeding = Breeding {
            ga: &self.ga,
            sigma: self.settings.sigma * if searching { 4.0 } else { 1.0 },
            immigrants: if searching { self.settings.immigrants } else { 0.0 },
            edge_moves: EdgeMoves {
                share: EDGE_MOVES,
                step: EDGE_STEP,
                box_px: self.box_px,
            },
        };
        self.pop.evolve(problem, generations, &breeding, &mut self.rng);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Texture terms of `stereo` and `structure`.
    const fn texture(stereo: f64, structure: f64) -> Texture {
        Texture { stereo, structure }
    }

    /// A tracker with the built-in configuration, of a 100 × 80 px photo box.
    fn tracker() -> Tracker {
        Tracker::new(&Config::load(None).expect("defaults"), [100.0, 80.0], 0)
    }

    /// The statuses `judge` gives a sequence of `(F_L + F_R, acquired)` with the default settings.
    fn statuses(frames: &[(f64, bool)]) -> Vec<TrackState> {
        let mut tracker = tracker();
        frames
            .iter()
            .map(|&(f, acquired)| tracker.judge(f, acquired, &NONE, || 0.0))
            .collect()
    }

    const T: TrackState = TrackState::Tracking;
    /// Texture terms: none (no texture read, or flat), both as a found pose has them,
    /// and only the two eyes' agreement (a blurred card).
    const NONE: Texture = texture(0.0, 0.0);
    const VOUCHES: Texture = texture(0.9, 0.92);
    const STEREO: Texture = texture(0.9, 0.6);
    /// The eyes agree, the photo's pattern does not show: the card turned half round.
    const TURNED: Texture = texture(1.0, 0.05);
    /// The card's pattern shows; the eyes disagree on the points near an occluder's edge.
    const BESIDE: Texture = texture(0.75, 0.6);
    const S: TrackState = TrackState::Searching;
    const L: TrackState = TrackState::Lost;

    #[test]
    fn a_fitness_well_below_the_best_since_acquisition_is_searching() {
        // 0.85 × 1.95 = 1.6575: F 1.60 is above min_fitness (1.0) but a slipped model.
        assert_eq!(
            statuses(&[(1.95, true), (1.94, false), (1.60, false), (1.90, false)]),
            [T, T, S, T]
        );
        // The reference rises with the best F: 0.85 × 2.2 = 1.87.
        assert_eq!(statuses(&[(1.95, true), (2.2, false), (1.85, false)]), [T, T, S]);
        // A fresh acquisition is the new reference, even when it is lower.
        assert_eq!(statuses(&[(1.95, true), (1.5, true), (1.45, false)]), [T, T, T]);
    }

    #[test]
    fn after_a_doubtful_relocation_tracking_needs_nearly_the_acquisitions_fitness() {
        let mut tracker = tracker();
        assert_eq!(tracker.judge(1.95, true, &NONE, || 0.0), T);
        // 1.75 is 0.90 of the acquisition's F: tracked unless in doubt.
        assert_eq!(tracker.judge(1.75, false, &NONE, || 0.0), T);
        tracker.doubt();
        assert_eq!(tracker.judge(1.75, false, &NONE, || 0.0), S);
        assert_eq!(tracker.judge(1.86, false, &NONE, || 0.0), T);
        // The doubt ends with a tracked frame.
        assert_eq!(tracker.judge(1.75, false, &NONE, || 0.0), T);
    }

    #[test]
    fn searching_too_long_is_lost_and_acquired_afresh() {
        let settings = TrackingSettings::default();
        let mut tracker = tracker();
        tracker.pop = LivePopulation::of(vec![[0.5; GENES]]);
        assert_eq!(tracker.judge(1.95, true, &NONE, || 0.0), T);
        for _ in 0..settings.lost_after_frames {
            assert_eq!(tracker.judge(1.5, false, &NONE, || 0.0), S);
            assert!(!tracker.needs_acquisition());
        }
        assert_eq!(tracker.judge(1.5, false, &NONE, || 0.0), L);
        assert!(tracker.needs_acquisition());
    }

    #[test]
    fn a_lost_object_is_recovered_from_its_last_tracked_pose_before_it_is_acquired() {
        let settings = TrackingSettings::default();
        let mut tracker = tracker();
        assert_eq!(tracker.plan(), Plan::Acquire, "nothing acquired yet");
        tracker.pop = LivePopulation::of(vec![[0.5; GENES]]);
        tracker.last_best = Some([0.5; GENES]);
        assert_eq!(tracker.plan(), Plan::Track);
        tracker.confirm();
        for _ in 0..=settings.lost_after_frames {
            tracker.judge(0.9, false, &NONE, || 0.0);
        }
        // Lost: the recoveries, one per frame (each counted by `step`), then an acquisition.
        for _ in 0..RECOVERIES {
            assert_eq!(tracker.plan(), Plan::Recover);
            assert!(tracker.prediction().is_none(), "a recovery searches the whole frame");
            tracker.recoveries -= 1;
            tracker.recovery_failed();
        }
        assert_eq!(tracker.plan(), Plan::Acquire);
        // An acquisition the verdict rejects is followed by recoveries again.
        tracker.reject_acquisition();
        assert_eq!(tracker.plan(), Plan::Recover);
        // A recovery that is tracked ends the loss.
        assert_eq!(tracker.judge(1.9, false, &NONE, || 0.0), T);
        tracker.confirm();
        assert_eq!(tracker.plan(), Plan::Track);
    }

    #[test]
    fn texture_that_vouches_or_eyes_that_agree_keep_a_card_tracked_but_never_below_the_floor() {
        let mut tracker = tracker();
        // F 0.73 is below min_fitness (1.0): searching on colour alone, tracking where
        // both eyes see the photo's texture at the pose.
        assert_eq!(tracker.judge(0.73, true, &NONE, || 0.0), S);
        assert_eq!(tracker.judge(0.73, true, &VOUCHES, || 0.0), T);
        // Also a slipped share of the best F (0.85 × 1.95 = 1.66) and a doubt.
        assert_eq!(tracker.judge(1.95, false, &NONE, || 0.0), T);
        tracker.doubt();
        assert_eq!(tracker.judge(1.2, false, &VOUCHES, || 0.0), T);
        assert!(!tracker.doubted(), "a tracked frame ends the doubt");
        // Blurred: F 1.6 is below 0.85 × 1.95, but the two eyes agree on the pose.
        assert_eq!(tracker.judge(1.6, false, &NONE, || 0.0), S);
        assert_eq!(tracker.judge(1.6, false, &STEREO, || 0.0), T);
        // Not in doubt, nor below min_fitness.
        assert_eq!(tracker.judge(0.9, false, &STEREO, || 0.0), S);
        tracker.doubt();
        assert_eq!(tracker.judge(1.6, false, &STEREO, || 0.0), S);
        // Below lost_fitness (0.5) nothing is tracked.
        assert_eq!(tracker.judge(0.45, false, &VOUCHES, || 0.0), L);
        assert_eq!(tracker.judge(f64::NAN, false, &VOUCHES, || 0.0), L);
    }

    /// The eyes agree on a card turned half round as on the card; its pattern does not.
    #[test]
    fn eyes_that_agree_on_something_without_the_photos_pattern_do_not_keep_it_tracked() {
        let mut tracker = tracker();
        assert_eq!(tracker.judge(1.95, true, &NONE, || 0.0), T);
        assert_eq!(tracker.judge(1.1, false, &TURNED, || 1.0), S);
        assert_eq!(tracker.judge(1.1, false, &STEREO, || 0.0), T);
    }

    /// An occluder's edge, seen at another place by each eye: the eyes' agreement on
    /// every point is low, on all but the disagreeing ones it holds.
    #[test]
    fn eyes_that_agree_beside_an_occluder_keep_a_card_tracked_but_not_in_doubt() {
        let mut tracker = tracker();
        assert_eq!(tracker.judge(1.95, true, &NONE, || 0.0), T);
        // F 1.3 is below 0.85 × 1.95: tracked if the trimmed agreement holds (0.85).
        assert_eq!(tracker.judge(1.3, false, &BESIDE, || 0.9), T);
        assert_eq!(tracker.judge(1.3, false, &BESIDE, || 0.8), S);
        // Not below min_fitness, nor in doubt.
        assert_eq!(tracker.judge(0.9, false, &BESIDE, || 0.95), S);
        tracker.doubt();
        assert_eq!(tracker.judge(1.3, false, &BESIDE, || 0.95), S);
    }

    /// After a frame below the floor, the pose drifted: `F_L + F_R` calls it tracked again
    /// only where the eyes agree on every point too.
    #[test]
    fn a_pose_that_drifted_while_lost_is_not_tracking_on_colour_alone() {
        let mut tracker = tracker();
        assert_eq!(tracker.judge(1.95, true, &NONE, || 0.0), T);
        assert_eq!(tracker.judge(0.4, false, &NONE, || 0.0), L);
        // 1.8 is above 0.85 × 1.95, but the eyes disagree (0.5) on every point.
        let drifted = texture(0.5, 0.8);
        assert_eq!(tracker.judge(1.8, false, &drifted, || 0.95), S);
        assert_eq!(tracker.judge(1.8, false, &texture(0.75, 0.8), || 0.95), T);
        // A tracked frame ends it.
        assert_eq!(tracker.judge(1.8, false, &drifted, || 0.95), T);
        // The texture vouches whatever the colour.
        assert_eq!(tracker.judge(0.4, false, &NONE, || 0.0), L);
        assert_eq!(tracker.judge(0.8, false, &VOUCHES, || 0.0), T);
        assert_eq!(tracker.judge(1.8, false, &drifted, || 0.95), T);
    }

    #[test]
    fn below_the_floor_or_nan_is_lost_at_once() {
        assert_eq!(
            statuses(&[(1.95, true), (0.4, false), (f64::NAN, false), (0.9, false)]),
            [T, L, L, S]
        );
    }
}
