//! The last step of the polish: a compass search along the moves a model makes on its
//! target (resize, one-sided resize, shift in its plane, along the line of sight with
//! or without its apparent size, tilt, roll). The fitness peaks sharply at the true
//! size and falls off unevenly on either side; an evolution strategy's step adapts
//! to the steepest side and then creeps along the gentle one. Steps along these
//! directions, halved when none improves, climb the ridge within a few hundred
//! evaluations.

use nalgebra::Vector3;

use super::{best_index, Genes, Problem, Ties};
use crate::estimator::fitness::Fitness;
use crate::estimator::pose::PoseSize;

/// First and last relative step (of size; positions and angles scale with it).
const FIRST_STEP: f64 = 0.04;
const LAST_STEP: f64 = 0.0025;
/// Radians of tilt or roll per unit of relative step.
const TURN_PER_STEP: f64 = 0.9;

/// The moves, each taken forward and back by the current step.
#[derive(Debug, Clone, Copy)]
enum Move {
    /// Length and width together, about the centre.
    Scale,
    /// Length or width (`true`: length), about the centre (`side` 0) or one edge.
    Resize(bool, f64),
    /// Along the model's own x or y axis, by the step times its length.
    Shift(Vector3<f64>),
    /// Along the left camera's line of sight, by the step times a quarter of the
    /// distance; with `keep_apparent`, the size grows with the distance.
    Sight { keep_apparent: bool },
    /// About the model's own axis.
    Turn(Vector3<f64>),
    /// About the model's own x (`true`) or y axis, its image's extent kept.
    TurnInView(bool),
}

const MOVES: [Move; 14] = [
    Move::Scale,
    Move::Resize(true, 0.0),
    Move::Resize(false, 0.0),
    Move::Resize(true, 0.5),
    Move::Resize(true, -0.5),
    Move::Resize(false, 0.5),
    Move::Resize(false, -0.5),
    Move::Shift(Vector3::new(1.0, 0.0, 0.0)),
    Move::Shift(Vector3::new(0.0, 1.0, 0.0)),
    Move::Sight { keep_apparent: false },
    Move::Sight { keep_apparent: true },
    Move::Turn(Vector3::new(1.0, 0.0, 0.0)),
    Move::Turn(Vector3::new(0.0, 1.0, 0.0)),
    Move::Turn(Vector3::new(0.0, 0.0, 1.0)),
];

/// `p` moved by `m` with the signed relative step `s`.
fn moved(problem: &Problem, p: &PoseSize, m: Move, s: f64) -> PoseSize {
    let box_px = problem.scorer.box_px;
    match m {
        Move::Scale => p.scaled(1.0 + s),
        Move::Resize(along_length, side) => p.resized(box_px, along_length, 1.0 + s, side),
        Move::Shift(axis) => {
            let length = p.size_mm(box_px[0], box_px[1])[0];
            PoseSize {
                position: p.position + p.rotation() * axis * (s * length),
                ..*p
            }
        }
        Move::Sight { keep_apparent } => {
            let q = PoseSize {
                position: p.position + p.sight(&problem.scorer.left_from_hand) * (s / 4.0),
                ..*p
            };
            if keep_apparent {
                q.scaled(1.0 + s / 4.0)
            } else {
                q
            }
        }
        Move::Turn(axis) => p.turned(axis, s * TURN_PER_STEP),
        Move::TurnInView(about_x) => {
            p.turned_in_view(&problem.scorer.left_from_hand, box_px, about_x, s * TURN_PER_STEP)
        }
    }
}

/// Climbs from `start` on `level` for at most `budget` evaluations; returns the best
/// and its fitness.
pub fn climb(problem: &Problem, level: usize, start: Genes, budget: usize) -> (Genes, Fitness) {
    climb_on(problem, level, start, budget, &MOVES)
}

/// The moves of [`turn_in_view`]'s climbs: those that keep the image's extent (shifts
/// in its plane, along the line of sight with the apparent size, turns in view, roll).
const IN_VIEW: [Move; 6] = [
    Move::Shift(Vector3::new(1.0, 0.0, 0.0)),
    Move::Shift(Vector3::new(0.0, 1.0, 0.0)),
    Move::Sight { keep_apparent: true },
    Move::TurnInView(true),
    Move::TurnInView(false),
    Move::Turn(Vector3::new(0.0, 0.0, 1.0)),
];

/// [`climb`] along `moves` only (at most [`MOVES`]' number).
fn climb_on(problem: &Problem, level: usize, start: Genes, budget: usize, moves: &[Move]) -> (Genes, Fitness) {
    let mut best = (start, problem.evaluate(level, &start));
    let mut step = FIRST_STEP;
    let mut used = 1;
    // On the stack: tracking frames climb too, and they must not allocate.
    let mut fit = [Fitness::default(); 2 * MOVES.len()];
    let n = 2 * moves.len();
    let fit = &mut fit[..n];
    while step >= LAST_STEP && used + n <= budget {
        let p = problem.bounds.decode(&best.0);
        // Past `moves`, the array holds copies of the best, which are not evaluated.
        let around: [Genes; 2 * MOVES.len()] = std::array::from_fn(|k| {
            let s = if k % 2 == 0 { step } else { -step };
            moves
                .get(k / 2)
                .map_or(best.0, |&m| problem.bounds.encode(&moved(problem, &p, m, s)))
        });
        let around = &around[..n];
        problem.evaluate_batch(level, around, fit);
        used += n;
        let i = best_index(fit, Ties::First);
        if fit[i].score > best.1.score {
            best = (around[i], fit[i]);
        } else {
            step /= 2.0;
        }
    }
    best
}

/// `start` (genes and fitness on `level`) turned by `step` radians about its own x or y
/// axis, again and again (at most `most` times each way) while that raises its score:
/// the turns of a card about an axis in its plane, larger than the climb's first steps.
pub fn turn_while_better(
    problem: &Problem,
    level: usize,
    start: (Genes, Fitness),
    step: f64,
    most: usize,
) -> (Genes, Fitness) {
    let mut best = start;
    for axis in [Vector3::x(), Vector3::y()] {
        for sign in [1.0, -1.0] {
            for _ in 0..most {
                let turned = problem.bounds.decode(&best.0).turned(axis, sign * step);
                let genes = problem.bounds.encode(&turned);
                let fitness = problem.evaluate(level, &genes);
                if fitness.score <= best.1.score {
                    break;
                }
                best = (genes, fitness);
            }
        }
    }
    best
}

/// The best of `start` and its copies resized over a wide range (×0.7 to ×1.4 in
/// steps of 3 %): both sides together about the centre, or one side about its centre
/// or either edge. The score has side peaks in size that the climb's small steps do
/// not cross (a model that matches an inner frame of its target, or its target plus a
/// margin). Returns the best and whether it is not `start`.
pub fn sweep_sizes(problem: &Problem, level: usize, start: Genes) -> (Genes, bool) {
    let p = problem.bounds.decode(&start);
    let factors: Vec<f64> = (-SWEEP_STEPS..=SWEEP_STEPS)
        .filter(|&k| k != 0)
        .map(|k| SWEEP_RATIO.powi(k))
        .collect();
    let resized = factors
        .iter()
        .map(|&f| p.scaled(f))
        .chain(p.resizes(problem.scorer.box_px, &factors));
    let candidates: Vec<Genes> = std::iter::once(start)
        .chain(resized.map(|q| problem.bounds.encode(&q)))
        .collect();
    let mut fit = vec![Fitness::default(); candidates.len()];
    problem.evaluate_batch(level, &candidates, &mut fit);
    let i = best_index(&fit, Ties::First);
    (candidates[i], i != 0)
}

/// The sweep's steps each way and their ratio: ×1.03^±12 ≈ ×0.70 to ×1.43.
const SWEEP_STEPS: i32 = 12;
const SWEEP_RATIO: f64 = 1.03;

/// `start` turned about its own x or y axis by 10° to 50° each way, its image's extent
/// kept ([`PoseSize::turned_in_view`]); the three best of those climbed on `level`
/// along the moves that keep that extent too, `budget` evaluations each. Returns the
/// best climbed, or `start` where none beats it. The image of a card barely tells a
/// tilt of 10° from one of 45° with the length cut by the cosine: a search can settle
/// on the wrong one, and no small step leaves it.
pub fn turn_in_view(problem: &Problem, level: usize, start: (Genes, Fitness), budget: usize) -> (Genes, Fitness) {
    let p = problem.bounds.decode(&start.0);
    let left_from_hand = &problem.scorer.left_from_hand;
    let mut candidates = Vec::new();
    for about_x in [false, true] {
        for deg in IN_VIEW_TURNS_DEG {
            for sign in [1.0, -1.0] {
                let q = p.turned_in_view(left_from_hand, problem.scorer.box_px, about_x, sign * deg.to_radians());
                if problem.bounds.contains(&q) {
                    candidates.push(problem.bounds.encode(&q));
                }
            }
        }
    }
    let mut fit = vec![Fitness::default(); candidates.len()];
    problem.evaluate_batch(level, &candidates, &mut fit);
    let mut order: Vec<usize> = (0..candidates.len()).collect();
    order.sort_by(|&a, &b| fit[b].score.total_cmp(&fit[a].score));
    let mut best = start;
    for &i in order.iter().take(TURN_STARTS) {
        let climbed = climb_on(problem, level, candidates[i], budget, &IN_VIEW);
        if climbed.1.score > best.1.score {
            best = climbed;
        }
    }
    best
}

/// Turns of [`turn_in_view`], degrees each way.
const IN_VIEW_TURNS_DEG: [f64; 5] = [10.0, 20.0, 30.0, 40.0, 50.0];
/// Candidates of [`turn_in_view`] climbed.
const TURN_STARTS: usize = 3;
