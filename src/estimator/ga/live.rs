//! A population that lives from frame to frame, for tracking (the lab's real-time
//! multi-step GA): seeded around an acquired pose, moved by the predicted motion on each
//! new frame, re-scored there and evolved a few generations. Everything is scored at
//! full resolution (pyramid level 0), and nothing allocates once the population has
//! reached its size.

use rand::Rng;

use super::robust::{mutate, mutate_from_edge, Population};
use super::{best_index, Genes, Problem, Ties};
use crate::estimator::fitness::Fitness;
use crate::estimator::settings::GaSettings;

/// How the children of a frame's generations are made: the GA's survivor share and
/// crossover rate, Gaussian mutation, random immigrants from the view prior, and
/// rescaling about an edge ([`EdgeMoves`]).
#[derive(Debug, Clone, Copy)]
pub struct Breeding<'a> {
    /// Survivor share and crossover rate.
    pub ga: &'a GaSettings,
    /// Mutation step, normalised gene units.
    pub sigma: f64,
    /// Share of the children drawn afresh from the view prior instead.
    pub immigrants: f64,
    /// Rescaling of some children about one of their edges.
    pub edge_moves: EdgeMoves,
}

/// Children also rescaled about one of their edges: a model that shrank onto part of a
/// target that moved further than predicted grows back along this ridge, which
/// single-gene mutations cross only by chance.
#[derive(Debug, Clone, Copy)]
pub struct EdgeMoves {
    /// Share of the children rescaled.
    pub share: f64,
    /// Spread of the rescaling (the log of the factor).
    pub step: f64,
    /// The photo box `[L_P, B_P]`, pixels.
    pub box_px: [f64; 2],
}

/// A GA population kept across frames; see the module documentation.
pub struct LivePopulation {
    pop: Population,
    /// Reused by each generation's sort.
    order: Vec<usize>,
}

impl LivePopulation {
    /// An empty population with room for `n` individuals.
    pub fn with_capacity(n: usize) -> Self {
        Self {
            pop: Population::new(Vec::with_capacity(n)),
            order: Vec::with_capacity(n),
        }
    }

    /// An unscored population of `genes` (tests).
    #[cfg(test)]
    pub(crate) fn of(genes: Vec<Genes>) -> Self {
        Self {
            order: Vec::with_capacity(genes.len()),
            pop: Population::new(genes),
        }
    }

    /// True before the first [`LivePopulation::seed_around`].
    pub fn is_empty(&self) -> bool {
        self.pop.genes.is_empty()
    }

    /// Replaces the population by `best` and `n − 1` copies of it mutated with step
    /// `sigma` (at least `best` itself), all scored on the problem's frame.
    pub fn seed_around(&mut self, problem: &Problem, best: Genes, n: usize, sigma: f64, rng: &mut impl Rng) {
        let genes = &mut self.pop.genes;
        genes.clear();
        genes.push(best);
        while genes.len() < n {
            let mut g = best;
            mutate(&mut g, &problem.bounds, sigma, rng);
            genes.push(g);
        }
        self.pop.fit.resize(genes.len(), Fitness::default());
        problem.evaluate_batch(0, genes, &mut self.pop.fit);
    }

    /// Moves every individual by `velocity` (clamped into the problem's bounds) and scores the
    /// whole population on the problem's frame: the previous frame's population, where
    /// the motion so far predicts it on the new one.
    pub fn shift(&mut self, problem: &Problem, velocity: &Genes) {
        for g in self.pop.genes.iter_mut() {
            for (i, (v, d)) in g.iter_mut().zip(velocity).enumerate() {
                *v = problem.bounds.clamp(i, *v + d);
            }
        }
        problem.evaluate_batch(0, &self.pop.genes, &mut self.pop.fit);
    }

    /// Runs `generations` generations on the problem's frame: sort, keep the best share,
    /// replace the others by children made as `breeding` says, score the children.
    pub fn evolve(&mut self, problem: &Problem, generations: usize, breeding: &Breeding, rng: &mut impl Rng) {
        let keep = breeding.ga.survivors_of(self.pop.genes.len());
        let edge = &breeding.edge_moves;
        for _ in 0..generations {
            self.pop.sort(&mut self.order);
            self.pop
                .breed(problem, keep, breeding.ga, breeding.sigma, breeding.immigrants, rng);
            for g in &mut self.pop.genes[keep..] {
                if rng.random::<f64>() < edge.share {
                    mutate_from_edge(g, &problem.bounds, edge.box_px, edge.step, rng);
                }
            }
            problem.evaluate_batch(0, &self.pop.genes[keep..], &mut self.pop.fit[keep..]);
        }
    }

    /// Replaces the worst individual by `genes`, which scored `fit`.
    pub fn inject(&mut self, genes: Genes, fit: Fitness) {
        let scores = self.pop.fit.iter().map(|f| f.score);
        let worst = scores.enumerate().min_by(|a, b| a.1.total_cmp(&b.1)).map(|(i, _)| i);
        if let Some(w) = worst {
            self.pop.genes[w] = genes;
            self.pop.fit[w] = fit;
        }
    }

    /// The best individual and its fitness (of equal scores the last, as tracking has
    /// always chosen); `None` while the population is empty.
    pub fn best(&self) -> Option<(Genes, Fitness)> {
        if self.is_empty() {
            return None;
        }
        let i = best_index(&self.pop.fit, Ties::Last);
        Some((self.pop.genes[i], self.pop.fit[i]))
    }
}
