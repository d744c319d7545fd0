//! Several hypotheses, each polished: the scan's best distinct placements and the GA's
//! result are each tried at a range of tilts (the scan places the model facing the
//! camera) and refined by a CMA-ES ([`super::cmaes`]) on the half and the full
//! resolution, where the texture terms rank candidates, then climbed by a compass search
//! ([`super::compass`]). Each is also tried grown: the scan often matches a uniform
//! part of its target. The best polished hypothesis wins. A search that
//! followed one population could settle on a same-coloured region while the target
//! sat elsewhere in the frame; this way each plausible region gets its own refinement.

use nalgebra::Vector3;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use super::{best_index, normal, Genes, Problem, Ties, GENES};
use crate::estimator::fitness::Fitness;
use crate::estimator::pose::PoseSize;

/// Variants tried per hypothesis: rolls (degrees), sizes (factors of the length), and
/// tilts (degrees) about 8 axes in the image plane.
const ROLLS_DEG: [f64; 3] = [-15.0, 0.0, 15.0];
const SCALES: [f64; 5] = [0.8, 0.9, 1.0, 1.1, 1.25];
const TILTS_DEG: [f64; 3] = [15.0, 30.0, 45.0];
const TILT_AXES: usize = 8;

/// Up to `n` of `candidates` (best first) that differ from each other's by at least
/// `apart_mm` in position or 15 % in length, and at most `per_octave` of each octave
/// of apparent size (length over depth).
pub fn distinct(problem: &Problem, candidates: &[Genes], n: usize, apart_mm: f64, per_octave: usize) -> Vec<Genes> {
    let mut kept: Vec<(Genes, PoseSize, i32)> = Vec::with_capacity(n);
    let [l_p, b_p] = problem.scorer.box_px;
    for g in candidates {
        let p = problem.bounds.decode(g);
        let depth = (problem.scorer.left_from_hand * nalgebra::Point3::from(p.position)).z;
        let octave = (p.size_mm(l_p, b_p)[0] / depth.max(1.0)).log2().floor() as i32;
        let near = |q: &PoseSize| (p.position - q.position).norm() < apart_mm && (p.alpha / q.alpha).ln().abs() < 0.15;
        let full = kept.iter().filter(|k| k.2 == octave).count() >= per_octave;
        if !full && !kept.iter().any(|(_, q, _)| near(q)) {
            kept.push((*g, p, octave));
            if kept.len() == n {
                break;
            }
        }
    }
    kept.into_iter().map(|(g, _, _)| g).collect()
}

/// `g` and its variants: rolled, resized and tilted ([`PoseSize::tilted`] about axes in the image
/// plane). The scan places the model facing the camera on a coarse grid of sizes and
/// rolls; each variant starts the polish nearer one of the true poses it may stand for.
fn variants(problem: &Problem, g: &Genes) -> Vec<Genes> {
    let p = problem.bounds.decode(g);
    let left_from_hand = &problem.scorer.left_from_hand;
    let mut out = Vec::new();
    for roll in ROLLS_DEG {
        let rolled = p.rolled(left_from_hand, roll.to_radians());
        for scale in SCALES {
            let sized = rolled.scaled(scale);
            out.push(problem.bounds.encode(&sized));
            for tilt in TILTS_DEG {
                for a in 0..TILT_AXES {
                    let angle = std::f64::consts::TAU * a as f64 / TILT_AXES as f64;
                    let axis = Vector3::new(angle.cos(), angle.sin(), 0.0);
                    out.push(
                        problem
                            .bounds
                            .encode(&sized.tilted(left_from_hand, axis, tilt.to_radians())),
                    );
                }
            }
        }
    }
    out
}

/// Larger copies of `p`, each placed at a grid of centres around the old one: a model
/// that matched part of its target (a uniform area of it, on the scan's coarse grid)
/// grows over the whole target from wherever inside it it sat.
fn grown(problem: &Problem, p: &PoseSize) -> Vec<Genes> {
    let [l_p, b_p] = problem.scorer.box_px;
    let [length, width] = p.size_mm(l_p, b_p);
    let mut out = Vec::new();
    for factor in GROWTH {
        let reach = (factor - 1.0) / 3.0;
        for (i, j) in (-1..=1).flat_map(|i| (-1..=1).map(move |j| (i, j))) {
            let mut q = p.scaled(factor);
            q.position += p.rotation() * Vector3::new(i as f64 * reach * length, j as f64 * reach * width, 0.0);
            out.push(problem.bounds.encode(&q));
        }
    }
    out
}

/// Size factors of [`grown`].
const GROWTH: [f64; 4] = [1.5, 2.0, 2.7, 3.5];

/// The best of `hypotheses` after each is tried twice, from the best of its
/// `variants` and from the best of its `grown` copies on `level`, refined there
/// (`coarse`); the `FINALISTS` best of those are refined on level 0 (`fine`),
/// `evaluations` each per stage. The refinements run side by side, one per worker
/// (each seeded from `rng`, so the result does not depend on the threads).
pub fn best(
    problem: &Problem,
    hypotheses: &[Genes],
    level: usize,
    evaluations: usize,
    rng: &mut impl Rng,
) -> (Genes, Fitness) {
    let mut starts = Vec::with_capacity(2 * hypotheses.len());
    for h in hypotheses {
        let p = problem.bounds.decode(h);
        let left_from_hand = &problem.scorer.left_from_hand;
        let grown_all: Vec<Genes> = ROLLS_DEG
            .iter()
            .flat_map(|r| grown(problem, &p.rolled(left_from_hand, r.to_radians())))
            .collect();
        starts.push(best_of(problem, level, variants(problem, h)));
        starts.push(best_of(problem, level, grown_all));
    }
    let serial = problem.serial();
    let mut coarse_results = side_by_side(problem, &starts, rng, |g, rng| {
        coarse(&serial, *g, level, evaluations, rng)
    });
    coarse_results.sort_by(|a, b| b.1.score.total_cmp(&a.1.score));
    let finalists: Vec<Genes> = coarse_results.iter().take(FINALISTS).map(|r| r.0).collect();
    let results = side_by_side(problem, &finalists, rng, |g, rng| fine(&serial, *g, evaluations, rng));
    let fits: Vec<Fitness> = results.iter().map(|r| r.1).collect();
    results[best_index(&fits, Ties::First)]
}

/// `search(start, rng)` for each of `starts`, one task per start on `problem`'s
/// workers, each with its own generator seeded from `rng`.
fn side_by_side(
    problem: &Problem,
    starts: &[Genes],
    rng: &mut impl Rng,
    search: impl Fn(&Genes, &mut StdRng) -> (Genes, Fitness) + Sync,
) -> Vec<(Genes, Fitness)> {
    let seeded: Vec<(Genes, u64)> = starts.iter().map(|g| (*g, rng.random())).collect();
    let mut out = vec![(Genes::default(), Fitness::default()); seeded.len()];
    problem.workers.each(&seeded, &mut out, |(g, seed)| {
        search(g, &mut StdRng::seed_from_u64(*seed))
    });
    out
}

/// How many of the coarse results are refined on level 0.
const FINALISTS: usize = 6;

/// `start` after one-sided resizes and CMA-ES on `level`. The start is also tried
/// upside down: the scan keeps one roll per place, and a photo turned half round
/// shows the same colours there.
fn coarse(problem: &Problem, start: Genes, level: usize, evaluations: usize, rng: &mut impl Rng) -> (Genes, Fitness) {
    let flipped = problem.bounds.encode(&problem.bounds.decode(&start).half_turned());
    let mut candidates = edge_variants(problem, &start);
    candidates.extend(edge_variants(problem, &flipped));
    let start = best_of(problem, level, candidates);
    super::cmaes::maximise(problem, level, start, 3.0 * SIGMA, evaluations, rng)
}

/// `start` after CMA-ES, one-sided resizes and CMA-ES again on level 0, then the
/// compass search, and again from the best of a wide sweep of sizes if that is better.
fn fine(problem: &Problem, start: Genes, evaluations: usize, rng: &mut impl Rng) -> (Genes, Fitness) {
    let (g, _) = super::cmaes::maximise(problem, 0, start, SIGMA, evaluations, rng);
    let g = best_of(problem, 0, edge_variants(problem, &g));
    let (g, _) = super::cmaes::maximise(problem, 0, g, SIGMA / 2.0, evaluations / 2, rng);
    let (g, fit) = super::compass::climb(problem, 0, g, evaluations);
    match super::compass::sweep_sizes(problem, 0, g) {
        (swept, true) => super::compass::climb(problem, 0, swept, evaluations / 2),
        _ => (g, fit),
    }
}

/// The best of `candidates` on `level` (the first of equals).
fn best_of(problem: &Problem, level: usize, candidates: Vec<Genes>) -> Genes {
    let mut fit = vec![Fitness::default(); candidates.len()];
    problem.evaluate_batch(level, &candidates, &mut fit);
    candidates[best_index(&fit, Ties::First)]
}

/// `g` and its one-sided resizes: the length or the width grown or shrunk by
/// [`EDGE_FACTORS`] about its centre, or while one of the two edges across it stays
/// put (an error of the aspect the scan cannot see, facing). A model that covers
/// only part of its target, one edge on the target's edge and the other inside, scores
/// a local peak that a mutation of one gene leaves only by chance.
fn edge_variants(problem: &Problem, g: &Genes) -> Vec<Genes> {
    let resized = problem.bounds.decode(g).resizes(problem.scorer.box_px, &EDGE_FACTORS);
    std::iter::once(*g)
        .chain(resized.iter().map(|q| problem.bounds.encode(q)))
        .collect()
}

/// Length or width factors of [`edge_variants`].
const EDGE_FACTORS: [f64; 4] = [0.8, 0.9, 1.12, 1.25];

/// Initial step (normalised gene units) of the polish at full resolution; three times
/// this on the coarser level.
const SIGMA: f64 = 0.01;

/// (1+λ) evolution strategy on `level` from `start` with a success-based step size
/// (from `sigma`); returns the best, its fitness and the evaluations used.
pub fn refine(
    problem: &Problem,
    level: usize,
    start: Genes,
    budget: usize,
    sigma: f64,
    rng: &mut impl Rng,
) -> (Genes, Fitness, usize) {
    let mut best = start;
    let mut best_fit = problem.evaluate(level, &best);
    let lambda = (4 * problem.workers.threads()).max(8);
    let (mut step, mut used) = (sigma / 2.0, 1);
    let mut kids = vec![[0.0; GENES]; lambda];
    let mut fit = vec![Fitness::default(); lambda];
    while used + lambda <= budget {
        for k in kids.iter_mut() {
            *k = best;
            for v in k.iter_mut() {
                *v = (*v + step * normal(rng)).clamp(0.0, 1.0);
            }
        }
        problem.evaluate_batch(level, &kids, &mut fit);
        used += lambda;
        let i = best_index(&fit, Ties::First);
        if fit[i].score > best_fit.score {
            (best, best_fit) = (kids[i], fit[i]);
            step = (step * 1.3).min(sigma * 2.0);
        } else {
            step = (step * 0.8).max(sigma / 30.0);
        }
    }
    (best, best_fit, used)
}
