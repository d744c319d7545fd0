//! The default search: a real-valued GA run coarse to fine over the image pyramid.
//!
//! On the coarsest level several independent populations (restarts) explore the whole
//! search space with random immigrants, on blurred images where the fitness peak is
//! wide; the best individuals continue on finer levels with shrinking mutation, and a
//! final (1+λ) evolution strategy refines the best at full resolution.

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::time::Instant;

use super::scan::Scanned;
use super::{best_index, rank, snapshot_generations, Bounds, Genes, Outcome, Problem, Snapshot, Ties, GENES};
use crate::estimator::fitness::Fitness;
use crate::estimator::pose::PoseSize;
use crate::estimator::settings::{GaSettings, RobustSettings};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

/// Distinct scan regions polished at the end, and evaluations per polish and level in
/// a search of 1000 generations.
const HYPOTHESES: usize = 8;
const POLISH: usize = 400;

/// Mutation step (normalised gene units) at the start of full-resolution generations;
/// each coarser level multiplies it by 3.
const SIGMA_FULL: f64 = 0.006;

/// A standard normal sample (Box–Muller).
pub(super) fn normal(rng: &mut impl Rng) -> f64 {
    let u1: f64 = rng.random::<f64>().max(1e-300);
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// Gaussian mutation of about two genes (at least one), clamped into `bounds`.
pub(super) fn mutate(g: &mut Genes, bounds: &Bounds, sigma: f64, rng: &mut impl Rng) {
    let forced = rng.random_range(0..GENES);
    for (i, v) in g.iter_mut().enumerate() {
        if i == forced || rng.random::<f64>() < 2.0 / GENES as f64 {
            *v = bounds.clamp(i, *v + sigma * normal(rng));
        }
    }
}

/// Rescales the model by a log-normal factor (`step` its spread) along its x or y axis
/// while one of its two edges across that axis stays put. A model of a `box_px` photo box
/// (`[L_P, B_P]`) that covers only part of its target, one edge on the target's edge and
/// the other inside it, grows back along this ridge, which single-gene mutations cross
/// only by chance.
pub(super) fn mutate_from_edge(g: &mut Genes, bounds: &Bounds, box_px: [f64; 2], step: f64, rng: &mut impl Rng) {
    let p = bounds.decode(g);
    let factor = (step * normal(rng)).exp();
    let along_length = rng.random::<bool>();
    // The centre moves away from the fixed edge by half the change of the extent.
    let side = if rng.random::<bool>() { 0.5 } else { -0.5 };
    let p = p.resized(box_px, along_length, factor, side);
    *g = bounds.encode(&p);
}

/// Blend crossover (BLX-0.25): each gene drawn between and slightly beyond the parents'
/// (clamped into `bounds`).
fn blend(a: &Genes, b: &Genes, bounds: &Bounds, rng: &mut impl Rng) -> Genes {
    std::array::from_fn(|i| {
        let u = rng.random_range(-0.25..1.25);
        bounds.clamp(i, a[i] + u * (b[i] - a[i]))
    })
}

/// Largest tilt away from facing the camera of a view-sampled candidate, degrees.
const PRIOR_TILT_DEG: f64 = 45.0;

/// A candidate drawn where the cameras can see it: a random left-image pixel at a random
/// depth of the search range, roughly facing the camera, random size and aspect. Most of
/// the hand-frame search box is outside the field of view; this prior is not.
pub fn view_sample(problem: &Problem, rng: &mut impl Rng) -> Genes {
    let level = &problem.levels[0];
    let (w, h) = (level.rig.width as f64, level.rig.height as f64);
    let (u, v) = (rng.random_range(0.05..0.95) * w, rng.random_range(0.05..0.95) * h);
    let b = &problem.bounds;
    let z = rng.random_range(b.lo[2]..b.hi[2]);
    let p = level.rig.left.ray(u, v) * z;
    let axis_angle = rng.random_range(0.0..std::f64::consts::TAU);
    let tilt = rng.random_range(0.0..PRIOR_TILT_DEG.to_radians());
    let roll = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
    let rotation = UnitQuaternion::from_scaled_axis(Vector3::new(axis_angle.cos(), axis_angle.sin(), 0.0) * tilt)
        * UnitQuaternion::from_scaled_axis(Vector3::z() * roll);
    let left_from_model = Isometry3::from_parts(Translation3::from(p), rotation);
    let hand_from_model = problem.scorer.left_from_hand.inverse() * left_from_model;
    let mut g = b.encode(&PoseSize::from_pose(&hand_from_model, [1.0, 1.0], 1.0, 1.0));
    g[6] = rng.random();
    g[7] = rng.random();
    g
}

/// One population: genes and their fitness, sorted best first after [`Population::sort`].
pub(super) struct Population {
    /// The individuals.
    pub genes: Vec<Genes>,
    /// Their fitness, once scored.
    pub fit: Vec<Fitness>,
    /// Reused by [`Population::sort`].
    scratch: Vec<(Genes, Fitness)>,
}

impl Population {
    /// The best `n` of `n · oversample` view-prior candidates on `level`.
    fn seeded(problem: &Problem, level: usize, n: usize, oversample: usize, rng: &mut impl Rng) -> Self {
        let mut all = Self::new((0..n * oversample.max(1)).map(|_| view_sample(problem, rng)).collect());
        problem.evaluate_batch(level, &all.genes, &mut all.fit);
        let mut order = Vec::new();
        all.sort(&mut order);
        all.genes.truncate(n);
        all.fit.truncate(n);
        all
    }

    /// Unscored individuals.
    pub fn new(genes: Vec<Genes>) -> Self {
        Self {
            fit: vec![Fitness::default(); genes.len()],
            scratch: Vec::with_capacity(genes.len()),
            genes,
        }
    }

    /// Sorts best first.
    pub fn sort(&mut self, order: &mut Vec<usize>) {
        rank(&self.fit, order);
        self.scratch.clear();
        self.scratch.extend(order.iter().map(|&i| (self.genes[i], self.fit[i])));
        for (k, &(g, f)) in self.scratch.iter().enumerate() {
            self.genes[k] = g;
            self.fit[k] = f;
        }
    }

    /// Replaces everything after the first `keep` by children of the survivors.
    pub fn breed(
        &mut self,
        problem: &Problem,
        keep: usize,
        ga: &GaSettings,
        sigma: f64,
        immigrants: f64,
        rng: &mut impl Rng,
    ) {
        for i in keep..self.genes.len() {
            self.genes[i] = if rng.random::<f64>() < immigrants {
                view_sample(problem, rng)
            } else {
                let a = self.genes[rng.random_range(0..keep)];
                let mut child = if rng.random::<f64>() < ga.crossover_rate {
                    blend(&a, &self.genes[rng.random_range(0..keep)], &problem.bounds, rng)
                } else {
                    a
                };
                mutate(&mut child, &problem.bounds, sigma, rng);
                child
            };
        }
    }
}

/// Generations per level, coarsest first, summing to `total`.
fn schedule(total: usize, share: &[f64]) -> Vec<usize> {
    let sum: f64 = share.iter().sum();
    let mut out: Vec<usize> = share
        .iter()
        .map(|s| (total as f64 * s / sum).round() as usize)
        .collect();
    let assigned: usize = out.iter().take(out.len() - 1).sum();
    if let Some(last) = out.last_mut() {
        *last = total.saturating_sub(assigned);
    }
    out
}

/// Runs the coarse-to-fine GA for `generations` generations, then the refinement,
/// seeded from `scanned` where an acquisition scan was already made on this problem
/// ([`scan::seeds`](super::scan::seeds) of `ga.population`; `None`: scanned here).
pub fn run(
    problem: &Problem,
    ga: &GaSettings,
    robust: &RobustSettings,
    generations: usize,
    seed: u64,
    progress: &mut dyn FnMut(usize),
    scanned: Option<Scanned>,
) -> Outcome {
    let mut rng = StdRng::seed_from_u64(seed);
    let levels = problem.levels.len().min(robust.pyramid_levels);
    let plan = schedule(generations, &robust.level_share[robust.level_share.len() - levels..]);
    let mut search = Search::new(problem, ga, robust, levels, generations);
    search.seed(&mut rng, scanned);
    for (step, &gens) in plan.iter().enumerate() {
        let level = levels - 1 - step;
        let start = Instant::now();
        search.evolve_on(level, gens, &mut rng, progress);
        if step == 0 {
            search.merge_restarts();
        }
        tracing::debug!("level {level}: {gens} generations in {:.0} ms", ms(start));
    }
    search.finish(&mut rng)
}

/// One run of the coarse-to-fine search: its populations (one per restart until they
/// merge after the coarsest level), the buffers of their evaluation, and what it reports.
struct Search<'p, 'a> {
    problem: &'p Problem<'a>,
    ga: &'p GaSettings,
    robust: &'p RobustSettings,
    /// Pyramid levels searched; the coarsest is `levels - 1`.
    levels: usize,
    /// One population per restart, then the merged one.
    pops: Vec<Population>,
    /// Reused by the populations' sorts.
    order: Vec<usize>,
    /// The individuals of every population scored in one parallel batch, and their fitness.
    batch: Vec<Genes>,
    batch_fit: Vec<Fitness>,
    /// Candidates evaluated so far.
    evaluations: usize,
    /// Generations run so far, of `generations`.
    generation: usize,
    generations: usize,
    /// Generations whose best individual is reported, and the reports.
    marks: Vec<usize>,
    snapshots: Vec<Snapshot>,
    /// Distinct regions the scan found, polished beside the GA's result at the end.
    hypotheses: Vec<Genes>,
}

impl<'p, 'a> Search<'p, 'a> {
    fn new(
        problem: &'p Problem<'a>,
        ga: &'p GaSettings,
        robust: &'p RobustSettings,
        levels: usize,
        generations: usize,
    ) -> Self {
        let all = ga.population * robust.restarts;
        Self {
            problem,
            ga,
            robust,
            levels,
            pops: Vec::with_capacity(robust.restarts),
            order: Vec::with_capacity(all),
            batch: Vec::with_capacity(all),
            batch_fit: Vec::with_capacity(all),
            evaluations: 0,
            generation: 0,
            generations,
            marks: snapshot_generations(generations),
            snapshots: Vec::new(),
            hypotheses: Vec::new(),
        }
    }

    /// The restarts' first populations: the first from the exhaustive scan (`scanned`,
    /// or made here; topped up from the view prior if it found fewer placements), the
    /// others from the view prior.
    fn seed(&mut self, rng: &mut impl Rng, scanned: Option<Scanned>) {
        let (problem, n) = (self.problem, self.ga.population);
        let start = Instant::now();
        let mut scanned = if self.levels > 1 {
            let scan = scanned.unwrap_or_else(|| super::scan::seeds(problem, n));
            self.hypotheses = super::polish::distinct(problem, &scan.regions, HYPOTHESES, 40.0, HYPOTHESES / 4);
            Some(scan.seeds).filter(|s| !s.is_empty())
        } else {
            None
        };
        tracing::debug!("acquisition scan: {:.0} ms", ms(start));
        let start = Instant::now();
        let oversample = self.robust.prior_samples;
        for r in 0..self.robust.restarts {
            match scanned.take().filter(|_| r == 0) {
                Some(mut genes) => {
                    while genes.len() < n {
                        genes.push(view_sample(problem, rng));
                    }
                    self.pops.push(Population::new(genes));
                }
                None => {
                    let coarsest = self.levels - 1;
                    self.pops
                        .push(Population::seeded(problem, coarsest, n, oversample, rng));
                    self.evaluations += n * oversample.max(1);
                }
            }
        }
        tracing::debug!("view-prior seeding: {:.0} ms", ms(start));
    }

    /// Scores individuals `from..` of every population on `level`, as one parallel batch.
    fn evaluate(&mut self, level: usize, from: usize) {
        self.batch.clear();
        for p in &self.pops {
            self.batch.extend_from_slice(&p.genes[from..]);
        }
        self.batch_fit.clear();
        self.batch_fit.resize(self.batch.len(), Fitness::default());
        self.problem.evaluate_batch(level, &self.batch, &mut self.batch_fit);
        self.evaluations += self.batch.len();
        let mut k = 0;
        for p in self.pops.iter_mut() {
            let fit = &mut p.fit[from..];
            fit.copy_from_slice(&self.batch_fit[k..k + fit.len()]);
            k += fit.len();
        }
    }

    /// Scores every population on `level`, then evolves them `gens` generations there
    /// with a mutation step that shrinks over the level (and random immigrants on the
    /// coarsest of several levels).
    fn evolve_on(&mut self, level: usize, gens: usize, rng: &mut impl Rng, progress: &mut dyn FnMut(usize)) {
        let keep = self.ga.survivor_count();
        self.evaluate(level, 0);
        let sigma0 = SIGMA_FULL * 3f64.powi(level as i32);
        let immigrants = if level == self.levels - 1 && self.levels > 1 {
            self.robust.immigrants
        } else {
            0.0
        };
        for g in 0..gens {
            let sigma = sigma0 * (1.0 - 0.66 * g as f64 / gens.max(1) as f64);
            for p in self.pops.iter_mut() {
                p.sort(&mut self.order);
                p.breed(self.problem, keep, self.ga, sigma, immigrants, rng);
            }
            self.evaluate(level, keep);
            self.generation += 1;
            if self.marks.contains(&self.generation) {
                let best = self.best();
                self.snapshots.push(Snapshot {
                    generation: self.generation,
                    best: self.problem.bounds.decode(&best),
                    fitness: self.problem.evaluate(0, &best),
                });
            }
            progress(self.generation);
            self.problem.observe(self.generation, level, || self.best());
        }
    }

    /// The restarts merge: the best `population` individuals of all of them continue.
    fn merge_restarts(&mut self) {
        if self.pops.len() < 2 {
            return;
        }
        let n = self.ga.population;
        let mut all = Population::new(self.pops.iter().flat_map(|p| p.genes.iter().copied()).collect());
        all.fit = self.pops.iter().flat_map(|p| p.fit.iter().copied()).collect();
        all.sort(&mut self.order);
        all.genes.truncate(n);
        all.fit.truncate(n);
        self.pops = vec![all];
    }

    /// The best individual of all populations (of equal scores the first).
    fn best(&self) -> Genes {
        let heads: Vec<Fitness> = self
            .pops
            .iter()
            .map(|p| p.fit[best_index(&p.fit, Ties::First)])
            .collect();
        let p = &self.pops[best_index(&heads, Ties::First)];
        p.genes[best_index(&p.fit, Ties::First)]
    }

    /// Evaluations per hypothesis and level of the polish: [`POLISH`] for a search of
    /// 1000 generations, in proportion for shorter ones (a tracker's re-acquisition),
    /// and at least 100.
    fn polish_budget(&self) -> usize {
        (POLISH * self.generations / 1000).max(100)
    }

    /// Refines the best individual at full resolution ([`refine`]) and reports.
    fn finish(mut self, rng: &mut impl Rng) -> Outcome {
        let start = Instant::now();
        let mut hypotheses = vec![self.best()];
        hypotheses.extend(self.hypotheses.iter().copied());
        let hypotheses = super::polish::distinct(self.problem, &hypotheses, HYPOTHESES + 1, 20.0, HYPOTHESES + 1);
        let (best, _) = super::polish::best(
            self.problem,
            &hypotheses,
            1.min(self.levels - 1),
            self.polish_budget(),
            rng,
        );
        tracing::debug!("{} hypotheses polished in {:.0} ms", hypotheses.len(), ms(start));
        let start = Instant::now();
        let (best, fitness, used) = refine(self.problem, best, self.robust.refine_evaluations, rng);
        tracing::debug!("refinement: {used} evaluations in {:.0} ms", ms(start));
        let best = self.problem.bounds.decode(&best);
        if let Some(last) = self.snapshots.last_mut() {
            last.best = best;
            last.fitness = fitness;
        }
        Outcome {
            best,
            fitness,
            generations: self.generations,
            searches: 1,
            evaluations: self.evaluations + used,
            snapshots: self.snapshots,
            verdict: Default::default(),
        }
    }
}

/// Milliseconds since `t`.
fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// (1+λ) evolution strategy at full resolution with a success-based step size.
fn refine(problem: &Problem, start: Genes, budget: usize, rng: &mut impl Rng) -> (Genes, Fitness, usize) {
    super::polish::refine(problem, 0, start, budget, SIGMA_FULL, rng)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schedule_splits_generations_by_share() {
        assert_eq!(schedule(1000, &[0.5, 0.25, 0.25]), vec![500, 250, 250]);
        assert_eq!(schedule(7, &[1.0, 1.0]), vec![4, 3]);
        assert_eq!(schedule(10, &[1.0]), vec![10]);
    }

    /// The search bounds of the tests, reaching `reach` beyond them.
    fn test_bounds(reach: f64) -> Bounds {
        Bounds {
            lo: [-300.0, -300.0, 300.0, -1.0, -1.0, -1.0, 0.5, 0.5],
            hi: [300.0, 300.0, 1200.0, 1.0, 1.0, 1.0, 10.0, 2.0],
            log_alpha: true,
            reach,
            held_size: None,
        }
    }

    #[test]
    fn operators_stay_in_the_bounds_and_only_positions_reach_beyond_them() {
        let mut rng = StdRng::seed_from_u64(9);
        for reach in [0.0, 0.5] {
            let bounds = test_bounds(reach);
            let (mut beyond, mut last) = (0, [0.0; GENES]);
            for _ in 0..1000 {
                let a: Genes = std::array::from_fn(|_| rng.random());
                let b: Genes = std::array::from_fn(|_| rng.random());
                let mut c = blend(&a, &b, &bounds, &mut rng);
                mutate(&mut c, &bounds, 0.5, &mut rng);
                let (position, rest) = c.split_at(3);
                assert!(position.iter().all(|v| (-reach..=1.0 + reach).contains(v)));
                assert!(rest.iter().all(|v| (0.0..=1.0).contains(v)));
                beyond += position.iter().filter(|v| !(0.0..=1.0).contains(*v)).count();
                last = c;
            }
            assert_eq!(
                beyond > 0,
                reach > 0.0,
                "reach {reach}: {beyond} position genes beyond 0-1"
            );
            assert_eq!(
                bounds.encode(&bounds.decode(&last)).map(|g| (g * 1e9).round()),
                last.map(|g| (g * 1e9).round())
            );
        }
        let mut same = [0.5; GENES];
        mutate(&mut same, &test_bounds(0.0), 0.01, &mut rng);
        assert!(same.iter().any(|&v| v != 0.5), "at least one gene mutates");
    }

    /// A tracked object's held size: mutation and crossover keep α and k within the
    /// share of the held ones, the pose genes free.
    #[test]
    fn a_held_size_stays_within_its_share() {
        let mut rng = StdRng::seed_from_u64(3);
        let held = [0.5, 0.4, 0.6, 0.5, 0.5, 0.5, 0.3, 0.7];
        let bounds = test_bounds(0.0).holding_size([held[6], held[7]], 0.05);
        let p = bounds.decode(&held);
        let mut x = [f64::INFINITY, f64::NEG_INFINITY];
        for _ in 0..1000 {
            let a: Genes = std::array::from_fn(|_| rng.random());
            let b: Genes = std::array::from_fn(|_| rng.random());
            let mut c = blend(&a, &b, &bounds, &mut rng);
            mutate(&mut c, &bounds, 0.5, &mut rng);
            let q = bounds.decode(&c);
            for r in [q.alpha / p.alpha, q.k / p.k] {
                assert!((1.0 / 1.05 - 1e-9..=1.05 + 1e-9).contains(&r), "{r}");
            }
            x = [x[0].min(c[0]), x[1].max(c[0])];
        }
        assert!(x[0] < 0.1 && x[1] > 0.9, "x ranged over {x:?}");
    }

    #[test]
    fn an_edge_rescale_keeps_one_edge_and_the_other_axis() {
        let bounds = test_bounds(0.0);
        let box_px = [200.0, 150.0];
        let start = PoseSize::from_pose(
            &Isometry3::from_parts(
                Translation3::new(10.0, -20.0, 600.0),
                UnitQuaternion::from_euler_angles(0.3, -0.2, 0.5),
            ),
            [180.0, 120.0],
            box_px[0],
            box_px[1],
        );
        // The edge lines along the model's own axes, hand frame: the offsets of the ±x
        // edges (length) along x, of the ±y edges (width) along y, and of the plane.
        let axes = [0, 1, 2].map(|i| start.rotation() * Vector3::ith(i, 1.0));
        let edges = |p: &PoseSize| {
            let [l, b] = p.size_mm(box_px[0], box_px[1]);
            let at = |i: usize| p.position.dot(&axes[i]);
            [
                at(0) + l / 2.0,
                at(0) - l / 2.0,
                at(1) + b / 2.0,
                at(1) - b / 2.0,
                at(2),
            ]
        };
        let before = edges(&start);
        let mut rng = StdRng::seed_from_u64(4);
        let mut kept = [0; 4];
        for _ in 0..400 {
            let mut g = bounds.encode(&start);
            mutate_from_edge(&mut g, &bounds, box_px, 0.05, &mut rng);
            let after = edges(&bounds.decode(&g));
            let still: Vec<bool> = (0..5).map(|i| (after[i] - before[i]).abs() < 1e-6).collect();
            // The plane, both edges of the other axis and one of the rescaled axis stay put.
            assert!(still[4], "{before:?} → {after:?}");
            assert_eq!(still.iter().filter(|s| **s).count(), 4, "{before:?} → {after:?}");
            kept[still.iter().position(|s| !s).unwrap()] += 1;
        }
        assert!(
            kept.iter().all(|&n| n > 60),
            "each edge moves about a quarter of the time: {kept:?}"
        );
    }
}
