//! Tracking across frames, as in the authors' real-time multi-step GA: the population
//! of the previous frame is moved by the predicted motion, re-scored on the new frame
//! and evolved for a few generations; the best individual is the frame's pose. When
//! the fitness stays low the search widens (immigrants), and after a while the object
//! is acquired afresh with the one-shot robust search.

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use nalgebra::Isometry3;

use crate::camera::StereoRig;
use crate::config::{Config, GaSettings, RobustSettings, TrackingSettings};
use crate::fitness::Fitness;
use crate::frame::Region;
use crate::ga::robust::{mutate, Population};
use crate::ga::{Genes, Problem, GENES};
use crate::messages::status;
use crate::pose::PoseSize;

/// The result for one frame.
#[derive(Debug, Clone, Copy)]
pub struct Estimate {
    pub best: PoseSize,
    /// Fitness of `best` on the tracking level.
    pub fitness: Fitness,
    /// Generations run on this frame.
    pub generations: u32,
    /// One of [`crate::messages::status`].
    pub status: u32,
}

/// A GA population that lives from frame to frame.
pub struct Tracker {
    settings: TrackingSettings,
    ga: GaSettings,
    robust: RobustSettings,
    pop: Population,
    order: Vec<usize>,
    rng: StdRng,
    /// Frames in a row below `min_fitness`.
    searching: usize,
    /// Best genes of the last frame and their change per frame (constant velocity).
    last_best: Option<Genes>,
    velocity: Genes,
    frames: u64,
}

impl Tracker {
    pub fn new(config: &Config, seed: u64) -> Self {
        let n = config.tracking.population;
        Self {
            settings: config.tracking.clone(),
            ga: config.ga.clone(),
            robust: config.robust.clone(),
            pop: Population::new(Vec::with_capacity(n)),
            order: Vec::with_capacity(n),
            rng: StdRng::seed_from_u64(seed),
            searching: 0,
            last_best: None,
            velocity: [0.0; GENES],
            frames: 0,
        }
    }

    /// True until the first acquisition, and after the object was lost.
    pub fn needs_acquisition(&self) -> bool {
        self.pop.genes.is_empty() || self.searching > self.settings.lost_after_frames
    }

    /// The genes expected on the next frame (last best moved by the estimated velocity);
    /// `None` while the object has to be acquired.
    pub fn prediction(&self) -> Option<Genes> {
        if self.needs_acquisition() {
            return None;
        }
        self.last_best
            .map(|b| std::array::from_fn(|i| (b[i] + self.velocity[i]).clamp(0.0, 1.0)))
    }

    /// Processes one frame.
    pub fn step(&mut self, problem: &Problem) -> Estimate {
        self.frames += 1;
        let generations = if self.needs_acquisition() {
            self.acquire(problem);
            self.settings.acquire_generations
        } else {
            self.track(problem);
            self.settings.generations_per_frame
        };
        let best_i = (0..self.pop.fit.len())
            .max_by(|&a, &b| self.pop.fit[a].score.total_cmp(&self.pop.fit[b].score))
            .unwrap_or(0);
        let best = self.pop.genes[best_i];
        let fitness = self.pop.fit[best_i];
        if let Some(last) = self.last_best {
            // Damped: a wrong prediction costs more than a missing one.
            self.velocity = std::array::from_fn(|i| 0.5 * (best[i] - last[i]));
        }
        self.last_best = Some(best);
        let tracked = fitness.f >= self.settings.min_fitness;
        self.searching = if tracked { 0 } else { self.searching + 1 };
        let status = if tracked {
            status::TRACKING
        } else if self.searching > self.settings.lost_after_frames {
            status::LOST
        } else {
            status::SEARCHING
        };
        Estimate {
            best: problem.bounds.decode(&best),
            fitness,
            generations: generations as u32,
            status,
        }
    }

    /// One-shot robust search, then a population around its answer.
    fn acquire(&mut self, problem: &Problem) {
        let seed = self.rng.random();
        let outcome = crate::ga::robust::run(
            problem,
            &self.ga,
            &self.robust,
            self.settings.acquire_generations,
            seed,
            &mut |_| {},
        );
        let best = problem.bounds.encode(&outcome.best);
        self.pop.genes.clear();
        self.pop.genes.push(best);
        while self.pop.genes.len() < self.settings.population {
            let mut g = best;
            mutate(&mut g, self.settings.sigma, &mut self.rng);
            self.pop.genes.push(g);
        }
        self.pop.fit.resize(self.pop.genes.len(), Fitness::default());
        problem.evaluate_batch(self.settings.level, &self.pop.genes, &mut self.pop.fit);
        self.searching = 0;
        self.last_best = None;
        self.velocity = [0.0; GENES];
    }

    /// Predicts, re-scores and evolves the population on a new frame.
    fn track(&mut self, problem: &Problem) {
        let level = self.settings.level;
        for g in self.pop.genes.iter_mut() {
            for (v, d) in g.iter_mut().zip(self.velocity) {
                *v = (*v + d).clamp(0.0, 1.0);
            }
        }
        problem.evaluate_batch(level, &self.pop.genes, &mut self.pop.fit);
        let keep =
            ((self.pop.genes.len() as f64 * self.ga.survivors).round() as usize).clamp(1, self.pop.genes.len() - 1);
        let immigrants = if self.searching > 0 {
            self.settings.immigrants
        } else {
            0.0
        };
        // Searching widens the mutation too.
        let sigma = self.settings.sigma * if self.searching > 0 { 4.0 } else { 1.0 };
        for _ in 0..self.settings.generations_per_frame {
            self.pop.sort(&mut self.order);
            self.pop
                .breed(problem, keep, &self.ga, sigma, immigrants, &mut self.rng);
            problem.evaluate_batch(level, &self.pop.genes[keep..], &mut self.pop.fit[keep..]);
        }
    }
}

/// Pixels of each eye (left, right) worth preparing for a model at `pose`: its
/// projected box, grown on every side by `grow` times its size and at least `min_px`
/// (the motion until the next frame and the population's spread). The whole image where
/// the box is behind a camera.
pub fn search_windows(
    rig: &StereoRig,
    left_from_hand: &Isometry3<f64>,
    pose: &PoseSize,
    box_px: [f64; 2],
    grow: f64,
    min_px: f64,
) -> [Region; 2] {
    let left_from_model = left_from_hand * pose.hand_from_model();
    let size = pose.size_mm(box_px[0], box_px[1]);
    let (w, h) = (rig.width as usize, rig.height as usize);
    let pad = |extent: f64| (grow * extent).max(min_px);
    [
        Region::covering(&rig.left, [(left_from_model, size)], w, h, pad),
        Region::covering(&rig.right, [(rig.right_from_left * left_from_model, size)], w, h, pad),
    ]
}
