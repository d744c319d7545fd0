//! One-shot estimation (the paper's experiment): a photo-model and one stereo frame →
//! the model's pose in the hand frame and its size.

use rand::rngs::StdRng;
use rand::SeedableRng;
use serde::Serialize;

use crate::camera::calibration::CalibrationError;
use crate::config::Config;
use crate::estimator::fitness::Fitness;
use crate::estimator::fitness::{OuterRule, PointSet, Scorer};
use crate::estimator::ga::{self, Bounds, Outcome, Problem};
use crate::estimator::model::PhotoModel;
use crate::estimator::pose::PoseSize;
use crate::estimator::settings::Mode;
use crate::estimator::verify::{hidden, plane, texture};
use crate::estimator::verify::{BrightnessPyramid, TextureTerm, Verdict};
use crate::vision::frame::{coarse_levels, StereoImages};
use crate::vision::lookup::LevelLookup;

/// The per-frame inputs of the search, prepared once.
pub struct Prepared {
    /// The fitness of the configured mode for this model.
    pub scorer: Scorer,
    /// The frame's lookup images at every pyramid level, level 0 at full resolution.
    pub levels: Vec<LevelLookup>,
    /// The model's points on each level.
    pub points: Vec<PointSet>,
    /// The search space, mapping normalised genes to pose and size.
    pub bounds: Bounds,
    /// The configured method, paper or robust.
    pub mode: Mode,
    /// Both eyes' brightness at every pyramid level (texture terms and verdict).
    pub brightness: BrightnessPyramid,
    /// The thinned model points the texture terms use on each level.
    pub texture_points: Vec<PointSet>,
}

impl Prepared {
    /// Builds the scorer and the colour pyramid for `images` (their size selects the
    /// calibration section).
    pub fn new(model: &PhotoModel, images: &StereoImages, config: &Config) -> Result<Self, CalibrationError> {
        let (w, h) = images.eye_size();
        let rig = config.calibration.rig_for_image(w, h)?;
        let mode = config.ga.mode;
        let levels = match mode {
            Mode::Paper => 1,
            Mode::Robust => config.robust.pyramid_levels,
        };
        let scorer = scorer_for(model, config);
        let start = std::time::Instant::now();
        // The coarse images once, for the colour lookups and the brightness alike.
        let coarse = coarse_levels(images, levels);
        let levels = LevelLookup::pyramid_of(images, &coarse, &rig, &scorer.texel_rule());
        let brightness = BrightnessPyramid::new(images, &coarse);
        tracing::debug!("frame preparation: {:.0} ms", start.elapsed().as_secs_f64() * 1e3);
        let bounds = Bounds::new(&config.search, model, mode == Mode::Robust);
        let points = ga::level_points(model, &scorer, levels.len(), mode == Mode::Robust);
        let texture_points = points
            .iter()
            .enumerate()
            .map(|(l, p)| p.every(TEXTURE_STRIDE.get(l).copied().unwrap_or(1)))
            .collect();
        Ok(Self {
            scorer,
            levels,
            points,
            bounds,
            mode,
            brightness,
            texture_points,
        })
    }

    /// The search problem over this frame (in robust mode with the texture terms).
    pub fn problem<'a>(&'a self, config: &Config) -> Problem<'a> {
        self.problem_on(config, self.levels.len())
    }

    /// [`Prepared::problem`] on the finest `levels` pyramid levels only: its search
    /// starts on a finer level, where small or faint targets still show.
    fn problem_on<'a>(&'a self, config: &Config, levels: usize) -> Problem<'a> {
        let levels = levels.clamp(1, self.levels.len());
        let (lookups, points) = (&self.levels[..levels], &self.points[..levels]);
        let problem = Problem::new(&self.scorer, lookups, points, self.bounds, config.ga.threads);
        let weight = config.robust.texture_weight;
        if self.mode == Mode::Paper || weight == 0.0 {
            return problem;
        }
        problem.with_texture(TextureTerm {
            pyramid: &self.brightness,
            points: &self.texture_points,
            weight,
            below_level: levels - 1,
            brightness_where_flat: false,
        })
    }

    /// What the plane sweep reads on this frame: every model point, both eyes at full
    /// resolution ([`plane::settle`]).
    pub fn two_eyes(&self) -> plane::TwoEyes<'_> {
        plane::TwoEyes {
            points: &self.points[0],
            rig: &self.levels[0].rig,
            eyes: self.brightness.eyes(0),
            left_from_hand: &self.scorer.left_from_hand,
        }
    }

    /// `outcome`'s pose moved to the plane on which the two eyes see the same
    /// brightness, its left image held ([`plane::settle`]), and its fitness read again on
    /// `problem`: the tilt and size that the colour fitness leaves to chance at steep tilts.
    /// A plane outside the search space is not taken.
    fn settle_plane(&self, problem: &Problem, outcome: &mut Outcome) {
        let two = self.two_eyes();
        if two.agreement(&outcome.best) < SETTLE_AGREEMENT {
            return;
        }
        let best = plane::settle(&two, &outcome.best, self.scorer.box_px);
        if !problem.bounds.contains(&best) {
            return;
        }
        outcome.fitness = problem.evaluate(0, &problem.bounds.encode(&best));
        outcome.verdict = self.verdict(&best);
        outcome.best = best;
    }

    /// `outcome`'s pose with the sides grown that something in front of the card hid
    /// and its edges and roll lined up with the photo ([`hidden::uncovered`], found or
    /// not); its fitness and verdict read again. Unchanged if the new pose leaves the
    /// search space.
    fn uncover(&self, problem: &Problem, outcome: &mut Outcome) {
        let box_px = self.scorer.box_px;
        let grown = hidden::uncovered(&self.two_eyes(), &outcome.best, box_px);
        if grown == outcome.best || !problem.bounds.contains(&grown) {
            return;
        }
        outcome.fitness = problem.evaluate(0, &problem.bounds.encode(&grown));
        outcome.verdict = self.verdict(&grown);
        outcome.best = grown;
    }

    /// `outcome`'s pose polished again from the half resolution ([`ga::polish::best`]),
    /// taken if it scores higher, with its verdict. The search's polish starts where its
    /// population stood; the refinement after it may leave the pose on a local peak of
    /// the full resolution that the half resolution's wider peak leads out of (a card
    /// tilted 40°, found 13 mm away, shrunk and turned).
    pub fn repolish(&self, problem: &Problem, outcome: &mut Outcome, seed: u64) {
        let mut rng = StdRng::seed_from_u64(seed);
        let start = problem.bounds.encode(&outcome.best);
        let level = 1.min(problem.levels.len() - 1);
        let (g, fitness) = ga::polish::best(problem, &[start], level, REPOLISH_EVALUATIONS, &mut rng);
        if fitness.score <= outcome.fitness.score {
            return;
        }
        outcome.best = problem.bounds.decode(&g);
        outcome.fitness = fitness;
        outcome.verdict = self.verdict(&outcome.best);
    }

    /// `outcome`'s pose turned to another plane with the same image
    /// ([`ga::compass::turn_in_view`]), taken where it scores higher, lies 10° or more
    /// from it, and the two eyes see it about as consistently (their brightness agreeing
    /// at most 0.02 less, their detail at least as well: the verdict's stereo term);
    /// with its verdict. A card found in part under a bar and grown back keeps the tilt
    /// the part had, which may be 30–40° off. Smaller turns are left: under a bar the
    /// score prefers tilts a few degrees off.
    fn turn_plane(&self, problem: &Problem, outcome: &mut Outcome) {
        let start = (problem.bounds.encode(&outcome.best), outcome.fitness);
        let (g, fitness) = ga::compass::turn_in_view(problem, 0, start, TURN_EVALUATIONS);
        let turned = problem.bounds.decode(&g);
        let angle = (outcome.best.rotation().inverse() * turned.rotation()).angle();
        if fitness.score <= outcome.fitness.score || angle < TURN_LEAST_DEG.to_radians() {
            return;
        }
        let two = self.two_eyes();
        if two.agreement(&turned) < two.agreement(&outcome.best) - TURN_AGREEMENT_SLACK {
            return;
        }
        let verdict = self.verdict(&turned);
        if verdict.texture.stereo < outcome.verdict.texture.stereo {
            return;
        }
        outcome.best = turned;
        outcome.fitness = fitness;
        outcome.verdict = verdict;
    }

    /// The verdict on `best`: texture terms on every model point at full resolution,
    /// and how much they drop when the pose is moved by the tolerance (see [`Verdict`]).
    pub fn verdict(&self, best: &PoseSize) -> Verdict {
        let texture = |p: &PoseSize| {
            texture::score(
                &self.points[0],
                &self.levels[0].rig,
                self.brightness.eyes(0),
                &self.scorer.left_from_hand,
                p,
                texture::Reading {
                    denoised: true,
                    partial_view: self.scorer.partial_view,
                    brightness_where_flat: false,
                },
            )
        };
        let at = texture(best);
        let drop = crate::estimator::verify::perturbations(best, &self.scorer.left_from_hand)
            .iter()
            .map(|p| at.sum() - texture(p).sum())
            .fold(f64::INFINITY, f64::min);
        let rig = &self.levels[0].rig;
        let tilt =
            crate::estimator::verify::tilt_disparity_px(best, self.scorer.box_px, rig, &self.scorer.left_from_hand);
        Verdict::of(at, drop, tilt)
    }
}

/// The least agreement of the two eyes' brightness over a result ([`plane::TwoEyes::agreement`])
/// for the plane sweep to run: below it the eyes see different surfaces over part of
/// the model (a bar in front of the card), too many for the sweep's trimmed agreement
/// to leave out. Unhidden cards start at 0.997 or more on the random set; a partly
/// hidden one that the sweep turned from 3° to 5–6° off, at 0.79–0.81.
const SETTLE_AGREEMENT: f64 = 0.9;

/// The least turn [`Prepared::turn_plane`] takes, degrees.
const TURN_LEAST_DEG: f64 = 10.0;

/// How much lower the two eyes' brightness may agree over a turned pose than before
/// ([`plane::TwoEyes::agreement`]) for [`Prepared::turn_plane`] to take it.
const TURN_AGREEMENT_SLACK: f64 = 0.02;

/// Evaluations of each climb of [`Prepared::turn_plane`].
const TURN_EVALUATIONS: usize = 300;

/// Evaluations per stage of [`Prepared::repolish`] (the search's own polish takes as many).
const REPOLISH_EVALUATIONS: usize = 400;

/// The texture terms read every n-th model point of level 0, 1, … (they cost more per
/// point than the colour test).
const TEXTURE_STRIDE: [usize; 3] = [4, 2, 2];

/// The fitness of the configured mode for `model`.
pub fn scorer_for(model: &PhotoModel, config: &Config) -> Scorer {
    let r = &config.robust;
    let (rule, min_cos, sat_tol) = match config.ga.mode {
        Mode::Paper => (OuterRule::RawHue, 0.0, 255),
        Mode::Robust => (OuterRule::ColorClass, r.min_facing_cos, r.sat_tolerance),
    };
    let mut scorer = Scorer::new(model, config.fitness, rule, min_cos, sat_tol, config.left_from_hand);
    if config.ga.mode == Mode::Robust {
        scorer.min_extent_px = r.min_extent_px;
        scorer.stereo_weight = r.stereo_weight;
        scorer.rank_by_sum = true;
        scorer.partial_view = true;
    }
    scorer
}

/// The tilt of the tilted placements of the later retries' scans: a card tilted 20–45°
/// is foreshortened by 6–30 % along one side.
const RETRY_SCAN_TILT_DEG: f64 = 35.0;

/// How a search of the robust one-shot differs from the first, by its number.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Retry {
    /// It starts one pyramid level finer (small or faint targets).
    finer: bool,
    /// Its scan tries tilted placements instead of facing ones.
    tilted: bool,
    /// Its scan is dense and ranks by structure too (a wall of the card's colours).
    dense: bool,
    /// Its result is kept only where the verdict finds it or it scores clearly higher
    /// ([`CLEAR_MARGIN`]). A dense scan one level finer reaches the smallest placements
    /// all over the image; where it finds nothing, its best may outscore a nearer pose
    /// of the searches before by a hair.
    found_only: bool,
}

impl Retry {
    /// Search 0 is the plain one; 1 starts finer, 2 scans tilted, 3 both; 4 and later
    /// scan densely (the slowest, when the others found nothing), every second one finer
    /// and then over small apparent sizes only ([`Problem::scan_small_only`]);
    /// from 5 on a result counts only where it is found or scores clearly higher.
    fn of(attempt: u64) -> Self {
        Self {
            finer: attempt % 2 == 1,
            tilted: (2..4).contains(&attempt),
            dense: attempt >= 4,
            found_only: attempt >= 5,
        }
    }
}

/// Runs the configured GA for `generations` generations from `seed`.
pub fn run(
    model: &PhotoModel,
    images: &StereoImages,
    config: &Config,
    generations: usize,
    seed: u64,
    progress: &mut dyn FnMut(usize),
) -> Result<Outcome, CalibrationError> {
    let prepared = Prepared::new(model, images, config)?;
    Ok(search(&prepared, config, generations, seed, progress))
}

/// Runs the configured GA on an already prepared frame; in robust mode it searches
/// again from the next seed while the verdict finds nothing (`[robust] retries`, each
/// search as `Retry::of` plans it) and keeps the best-scoring result, its hidden sides
/// uncovered and, where the verdict still finds nothing, its plane turned
/// (`Prepared::turn_plane`).
pub fn search(
    prepared: &Prepared,
    config: &Config,
    generations: usize,
    seed: u64,
    progress: &mut dyn FnMut(usize),
) -> Outcome {
    search_observed(prepared, config, generations, seed, progress, None)
}

/// [`search`], telling `observer` each generation's best individual (`estimate --rerun`).
pub fn search_observed(
    prepared: &Prepared,
    config: &Config,
    generations: usize,
    seed: u64,
    progress: &mut dyn FnMut(usize),
    observer: Option<ga::observe::Observer<'_>>,
) -> Outcome {
    if prepared.mode == Mode::Paper {
        let mut problem = prepared.problem(config);
        problem.observer = observer;
        let mut outcome = ga::paper::run(&problem, &config.ga, generations, seed, progress);
        outcome.verdict = prepared.verdict(&outcome.best);
        return outcome;
    }
    let mut best: Option<Outcome> = None;
    for attempt in 0..=config.robust.retries as u64 {
        let seed = seed.wrapping_add(attempt);
        let retry = Retry::of(attempt);
        let levels = (prepared.levels.len() - retry.finer as usize).max(1);
        if attempt > 0 {
            tracing::info!("not found; searching again from seed {seed} on {levels} pyramid levels");
        }
        // An observer sees the searches one after another: generations count on.
        let offset = attempt as usize * generations;
        let shifted = observer.map(|o| {
            move |g: &ga::observe::Generation| {
                o(&ga::observe::Generation {
                    generation: g.generation + offset,
                    ..*g
                })
            }
        });
        let mut problem = prepared.problem_on(config, levels);
        problem.observer = shifted.as_ref().map(|o| o as ga::observe::Observer<'_>);
        problem.scan_dense = retry.dense;
        problem.scan_small_only = retry.dense && retry.finer;
        if retry.tilted {
            problem.scan_tilt = RETRY_SCAN_TILT_DEG.to_radians();
        }
        let mut outcome = ga::robust::run(&problem, &config.ga, &config.robust, generations, seed, progress, None);
        outcome.verdict = prepared.verdict(&outcome.best);
        if !outcome.verdict.found {
            prepared.repolish(&prepared.problem(config), &mut outcome, seed);
        }
        prepared.settle_plane(&problem, &mut outcome);
        let found = outcome.verdict.found;
        best = Some(better(best, outcome, retry.found_only));
        if found {
            break;
        }
    }
    let mut best = best.expect("at least one search");
    prepared.uncover(&prepared.problem(config), &mut best);
    if !best.verdict.found {
        prepared.turn_plane(&prepared.problem(config), &mut best);
    }
    best
}

/// How much higher a search that counts only where found ([`Retry::found_only`]) must
/// score to be kept though not found. On 116 of the 119 random scenes where the sixth
/// search ran, it scored at most 0.11 above the five before; on two, 1.2 and 1.3
/// above, it was the card (1.2 and 1.5 mm off), and on one 5.0 above five scores of 0.
const CLEAR_MARGIN: f64 = 0.5;

/// The higher-scoring of two searches' outcomes (of equal scores the earlier), counting
/// the searches and evaluations of both. A later one not found, from a search that
/// counts only where found (`found_only`), must score [`CLEAR_MARGIN`] higher.
fn better(earlier: Option<Outcome>, later: Outcome, found_only: bool) -> Outcome {
    match earlier {
        None => later,
        Some(e) => {
            let (evaluations, searches) = (e.evaluations + later.evaluations, e.searches + later.searches);
            let margin = if found_only && !later.verdict.found {
                CLEAR_MARGIN
            } else {
                0.0
            };
            let kept = if e.fitness.score + margin >= later.fitness.score {
                e
            } else {
                later
            };
            Outcome {
                evaluations,
                searches,
                ..kept
            }
        }
    }
}

/// The `--json` report: exactly the fields of the estimate contract.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Report {
    /// Model origin `(x, y, z)` in the hand frame, mm.
    pub position_mm: [f64; 3],
    /// Model orientation in the hand frame, unit quaternion `[w, x, y, z]` with `w ≥ 0`.
    pub orientation_wxyz: [f64; 4],
    /// Object size `[L, B]` along model x and y, mm.
    pub size_mm: [f64; 2],
    /// PM ratio `α` along model x, photo pixels per mm.
    pub alpha: f64,
    /// Ratio factor `k = β / α`.
    pub k: f64,
    /// Fitness `F` (eq. 18); 2 for a perfect match.
    pub fitness: f64,
    /// `F_L`, the left image's score.
    pub fitness_left: f64,
    /// `F_R`, the right image's score.
    pub fitness_right: f64,
    /// Generations run.
    pub generations: usize,
    /// The frame the pose is in: always "hand".
    pub frame: &'static str,
    /// Whether the object is judged found at this pose (see [`Verdict`]).
    pub found: bool,
    /// Confidence in the pose, 0–1.
    pub confidence: f64,
}

impl Report {
    /// The report of `outcome`'s best individual (sizes from `model`'s `L_P`, `B_P`).
    pub fn new(model: &PhotoModel, outcome: &Outcome) -> Self {
        let b: &PoseSize = &outcome.best;
        Self {
            position_mm: [b.position.x, b.position.y, b.position.z],
            orientation_wxyz: b.orientation_wxyz(),
            size_mm: b.size_mm(model.l_p, model.b_p),
            alpha: b.alpha,
            k: b.k,
            fitness: outcome.fitness.f,
            fitness_left: outcome.fitness.left,
            fitness_right: outcome.fitness.right,
            generations: outcome.generations,
            frame: "hand",
            found: outcome.verdict.found,
            confidence: outcome.verdict.confidence,
        }
    }
}

/// The paper's Table 2: one row per snapshot (x y z ε1 ε2 ε3 α β L B F).
pub fn table(model: &PhotoModel, outcome: &Outcome) -> String {
    let mut s = format!(
        "{:>10} {:>7} {:>7} {:>7} {:>6} {:>6} {:>6} {:>6} {:>6} {:>6} {:>6} {:>7}\n",
        "generation", "x[mm]", "y[mm]", "z[mm]", "ε1", "ε2", "ε3", "α", "β", "L[mm]", "B[mm]", "F"
    );
    for snap in &outcome.snapshots {
        let b = &snap.best;
        let [l, bb] = b.size_mm(model.l_p, model.b_p);
        let q = b.orientation_wxyz();
        s += &format!(
            "{:>10} {:>7.1} {:>7.1} {:>7.1} {:>6.3} {:>6.3} {:>6.3} {:>6.3} {:>6.3} {:>6.1} {:>6.1} {:>7.4}\n",
            snap.generation,
            b.position.x,
            b.position.y,
            b.position.z,
            q[1],
            q[2],
            q[3],
            b.alpha,
            b.beta(),
            l,
            bb,
            snap.fitness.f
        );
    }
    s
}

/// The fitness of `pose` on `images` at full resolution, evaluated on the same problem
/// [`run`] searches (so its `score` ranks against an outcome's): e.g. the ground truth's
/// score, to tell a search that missed the peak from a fitness whose peak is elsewhere.
pub fn score_at(
    model: &PhotoModel,
    images: &StereoImages,
    config: &Config,
    pose: &PoseSize,
) -> Result<Fitness, CalibrationError> {
    let prepared = Prepared::new(model, images, config)?;
    let problem = prepared.problem(config);
    Ok(problem.evaluate(0, &problem.bounds.encode(pose)))
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;

    use super::{better, Retry};
    use crate::estimator::fitness::Fitness;
    use crate::estimator::ga::Outcome;
    use crate::estimator::pose::PoseSize;
    use crate::estimator::verify::Verdict;

    /// One search's outcome: `x` mm along the hand's x, scoring `score`, found or not.
    fn outcome(x: f64, score: f64, found: bool) -> Outcome {
        Outcome {
            best: PoseSize {
                position: Vector3::new(x, 0.0, 600.0),
                eps: Vector3::zeros(),
                alpha: 2.0,
                k: 1.0,
            },
            fitness: Fitness {
                score,
                ..Fitness::default()
            },
            generations: 300,
            searches: 1,
            evaluations: 1000,
            snapshots: Vec::new(),
            verdict: Verdict {
                found,
                ..Verdict::default()
            },
        }
    }

    #[test]
    fn a_later_search_is_kept_where_it_scores_higher_or_clearly_higher_if_found_only() {
        let kept = |later: Outcome, found_only: bool| better(Some(outcome(0.0, 5.40, false)), later, found_only);
        // Higher: kept, both searches counted.
        let higher = kept(outcome(1.0, 5.49, false), false);
        assert_eq!(
            (higher.best.position.x, higher.searches, higher.evaluations),
            (1.0, 2, 2000)
        );
        // A found-only search's result, not found, only where it scores 0.5 higher.
        assert_eq!(kept(outcome(1.0, 5.89, false), true).best.position.x, 0.0);
        assert_eq!(kept(outcome(1.0, 5.91, false), true).best.position.x, 1.0);
        // Found, it counts as any other.
        assert_eq!(kept(outcome(1.0, 5.49, true), true).best.position.x, 1.0);
        // Equal scores keep the earlier.
        assert_eq!(kept(outcome(1.0, 5.40, true), false).best.position.x, 0.0);
        assert_eq!(better(None, outcome(2.0, 1.0, false), true).best.position.x, 2.0);
    }

    #[test]
    fn retries_start_finer_then_tilt_then_scan_densely() {
        let plan: Vec<[bool; 4]> = (0..6)
            .map(Retry::of)
            .map(|r| [r.finer, r.tilted, r.dense, r.found_only])
            .collect();
        assert_eq!(
            plan,
            [
                [false, false, false, false],
                [true, false, false, false],
                [false, true, false, false],
                [true, true, false, false],
                [false, false, true, false],
                [true, false, true, true],
            ]
        );
    }
}
