//! Relocation: an object acquired on an older frame, found again on the newest one.
//!
//! An acquisition takes about a second, in which the object may move far beyond the
//! tracker's window (at 150 mm/s, 20 cm). Its orientation and size change little in that
//! time, so the acquired pose is mostly translated: the model is placed on a grid over
//! the left image (a sixth of its apparent size apart, where the coarsest pyramid level's
//! blurred fitness peak is wider than that), at a few depths around the acquired one and
//! a few turns about the line of sight, and the best placements are climbed level by
//! level up to full resolution.
//!
//! The same search recovers a lost object from its last tracked pose (see
//! [`Plan::Recover`](crate::estimator::tracking::Plan::Recover)).

use nalgebra::{Isometry3, Point3};

use super::{compass, rank, Genes, Problem};
use crate::estimator::fitness::Fitness;
use crate::estimator::pose::PoseSize;

/// Depths tried, as factors of the acquired depth (along the left camera's axis).
const DEPTHS: [f64; 3] = [0.85, 1.0, 1.18];
/// Turns about the line of sight tried, degrees (the climbs take smaller ones).
const ROLLS_DEG: [f64; 3] = [-12.0, 0.0, 12.0];
/// Grid steps per apparent size of the model's shorter side.
const STEPS_PER_SIZE: f64 = 6.0;
/// Placements of each depth and turn climbed on the coarsest level; each finer level
/// climbs a third as many (and the original pose), with at most [`CLIMB`] evaluations
/// each. The coarse level cannot tell the depths apart as well as the finer ones.
const PER_GROUP: usize = 2;
const CLIMB: usize = 200;

/// The placement of `from` translated so its origin lies on the left camera's ray
/// through full-resolution pixel `(u, v)` at depth `z` (orientation and size unchanged;
/// `hand_from_left` the inverse hand–eye transform).
fn placed(problem: &Problem, hand_from_left: &Isometry3<f64>, from: &PoseSize, u: f64, v: f64, z: f64) -> Genes {
    let ray = problem.levels[0].rig.left.ray(u, v);
    let origin = hand_from_left * Point3::from(ray * z);
    problem.bounds.encode(&PoseSize {
        position: origin.coords,
        ..*from
    })
}

/// Every placement of `from` (a model of photo box `box_px`) on the grid over the left
/// image, in one group per combination of [`ROLLS_DEG`] and [`DEPTHS`].
fn placements(problem: &Problem, from: &PoseSize, box_px: [f64; 2]) -> Vec<Vec<Genes>> {
    let left_from_hand = problem.scorer.left_from_hand;
    let rig = &problem.levels[0].rig;
    let coarse = &problem.levels[problem.levels.len() - 1];
    let z0 = (left_from_hand * Point3::from(from.position)).z.max(1.0);
    let [l, b] = from.size_mm(box_px[0], box_px[1]);
    let apparent_px = rig.left.fx * l.min(b) / z0;
    let step = (apparent_px / STEPS_PER_SIZE).max(1.0 / coarse.scale);
    let (cols, rows) = ((rig.width as f64 / step) as usize, (rig.height as f64 / step) as usize);
    let hand_from_left = left_from_hand.inverse();
    let grid = |turned: &PoseSize, z: f64| -> Vec<Genes> {
        (0..rows)
            .flat_map(|r| (0..cols).map(move |c| ((c as f64 + 0.5) * step, (r as f64 + 0.5) * step)))
            .map(|(u, v)| placed(problem, &hand_from_left, turned, u, v, z))
            .collect()
    };
    ROLLS_DEG
        .iter()
        .map(|roll| from.rolled(&left_from_hand, roll.to_radians()))
        .flat_map(|turned| DEPTHS.map(|factor| grid(&turned, z0 * factor)))
        .collect()
}

/// The `n` best of `genes` on `level`.
fn best_of(problem: &Problem, level: usize, genes: &[Genes], n: usize) -> Vec<Genes> {
    let mut fit = vec![Fitness::default(); genes.len()];
    problem.evaluate_batch(level, genes, &mut fit);
    let mut order = Vec::new();
    rank(&fit, &mut order);
    order.iter().take(n).map(|&i| genes[i]).collect()
}

/// The translation of `from` (a model of photo box `box_px`) that scores best on the
/// problem's frame, with its fitness at full resolution. The best grid placements of
/// each depth and turn are climbed ([`compass::climb`]) on the coarsest level, and the
/// best of those climbed again on each finer one; `from` itself is climbed on every
/// level, so an object that did not move keeps its pose unless a placement scores higher.
pub fn relocate(problem: &Problem, from: &PoseSize, box_px: [f64; 2]) -> (Genes, Fitness) {
    let start = std::time::Instant::now();
    let original = problem.bounds.encode(from);
    let coarsest = problem.levels.len() - 1;
    let groups = placements(problem, from, box_px);
    let candidates: Vec<Genes> = std::iter::once(original)
        .chain(groups.iter().flat_map(|g| best_of(problem, coarsest, g, PER_GROUP)))
        .collect();
    let best = climbed_level_by_level(problem, candidates, Some(original), CLIMB);
    let ms = start.elapsed().as_secs_f64() * 1e3;
    tracing::debug!(
        "relocation: {} placements in {ms:.0} ms",
        groups.iter().map(Vec::len).sum::<usize>()
    );
    best
}

/// The best of `candidates` after each is climbed ([`compass::climb`], at most `budget`
/// evaluations) on the coarsest level, and the best third of those (at least 2) on each
/// finer one in turn, with its fitness at full resolution. `kept` (an object's pose
/// before) is climbed again on every level. The climbs of a level run side by side, one
/// per worker: a relocation took 21 ms instead of 56 ms on the README's frame.
pub fn climbed_level_by_level(
    problem: &Problem,
    mut candidates: Vec<Genes>,
    kept: Option<Genes>,
    budget: usize,
) -> (Genes, Fitness) {
    let serial = problem.serial();
    let mut keep = candidates.len();
    let mut climbed = Vec::new();
    for level in (0..problem.levels.len()).rev() {
        let starts = &candidates[..keep.min(candidates.len())];
        climbed = vec![(Genes::default(), Fitness::default()); starts.len()];
        problem
            .workers
            .each(starts, &mut climbed, |&g| compass::climb(&serial, level, g, budget));
        climbed.sort_by(|a, b| b.1.score.total_cmp(&a.1.score));
        candidates = kept.into_iter().chain(climbed.iter().map(|c| c.0)).collect();
        keep = (keep / 3).max(2);
    }
    climbed[0]
}
