//! Watching a one-shot search generation by generation (`estimate --rerun`): an optional
//! observer on the [`Problem`], told each generation's best individual. Without one the
//! search does no extra work.

use super::{Genes, Problem};
use crate::estimator::fitness::Fitness;
use crate::estimator::pose::PoseSize;

/// One generation of a search as its observer sees it.
#[derive(Debug, Clone, Copy)]
pub struct Generation {
    /// Generations run so far.
    pub generation: usize,
    /// The pyramid level the generation was searched on (0: full resolution).
    pub level: usize,
    /// The best individual's pose and size.
    pub best: PoseSize,
    /// Its fitness at full resolution (comparable across levels).
    pub fitness: Fitness,
}

/// Called once per generation; shared with the worker threads, hence `Sync`.
pub type Observer<'a> = &'a (dyn Fn(&Generation) + Sync);

impl Problem<'_> {
    /// Tells the observer, if there is one, generation `generation`'s best individual
    /// (`best` is only called then) searched on `level`.
    pub fn observe(&self, generation: usize, level: usize, best: impl FnOnce() -> Genes) {
        if let Some(observer) = self.observer {
            let genes = best();
            observer(&Generation {
                generation,
                level,
                best: self.bounds.decode(&genes),
                fitness: self.evaluate(0, &genes),
            });
        }
    }
}
