//! Worker threads for the fitness: persistent pools (threads are started once per
//! process, not per batch), shared by every search with the same thread count.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};

use rayon::prelude::*;

/// A handle on a pool of `threads` workers (1: the calling thread alone).
#[derive(Clone)]
pub struct Workers {
    threads: usize,
    pool: Option<Arc<rayon::ThreadPool>>,
}

impl std::fmt::Debug for Workers {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Workers({})", self.threads)
    }
}

impl Workers {
    /// `threads` workers; 0 means one per core. Pools are created on first use and kept.
    pub fn new(threads: usize) -> Self {
        // Asking the system for the core count reads files (and allocates): once.
        static CORES: OnceLock<usize> = OnceLock::new();
        let threads = if threads == 0 {
            *CORES.get_or_init(|| std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1))
        } else {
            threads
        };
        if threads <= 1 {
            return Self { threads: 1, pool: None };
        }
        static POOLS: OnceLock<Mutex<HashMap<usize, Arc<rayon::ThreadPool>>>> = OnceLock::new();
        let mut pools = POOLS
            .get_or_init(Default::default)
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        if let Some(pool) = pools.get(&threads) {
            return Self {
                threads,
                pool: Some(pool.clone()),
            };
        }
        let built = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .thread_name(|i| format!("photopose-fitness-{i}"))
            .start_handler(crate::estimator::realtime::worker_started)
            .build();
        match built {
            Ok(pool) => {
                let pool = Arc::new(pool);
                pools.insert(threads, pool.clone());
                Self {
                    threads,
                    pool: Some(pool),
                }
            }
            Err(e) => {
                tracing::warn!("cannot start {threads} fitness threads ({e}); using one");
                Self { threads: 1, pool: None }
            }
        }
    }

    /// Number of workers (1: no pool, the calling thread works alone).
    pub fn threads(&self) -> usize {
        self.threads
    }

    /// `out[i] = f(&items[i])`, one task per item: for a few long tasks (whole
    /// searches), which [`Workers::fill`]'s chunks would leave on one worker.
    pub fn each<T: Sync, R: Send>(&self, items: &[T], out: &mut [R], f: impl Fn(&T) -> R + Sync) {
        match &self.pool {
            Some(pool) => pool.install(|| items.par_iter().zip(out.par_iter_mut()).for_each(|(x, o)| *o = f(x))),
            None => items.iter().zip(out.iter_mut()).for_each(|(x, o)| *o = f(x)),
        }
    }

    /// `out[i] = f(&items[i])`, split into one contiguous chunk per worker.
    pub fn fill<T: Sync, R: Send>(&self, items: &[T], out: &mut [R], f: impl Fn(&T) -> R + Sync) {
        let chunk = items.len().div_ceil(self.threads).max(8);
        match &self.pool {
            Some(pool) if items.len() > chunk => pool.install(|| {
                items
                    .par_chunks(chunk)
                    .zip(out.par_chunks_mut(chunk))
                    .for_each(|(xs, os)| xs.iter().zip(os.iter_mut()).for_each(|(x, o)| *o = f(x)))
            }),
            _ => items.iter().zip(out.iter_mut()).for_each(|(x, o)| *o = f(x)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Workers;

    #[test]
    fn each_and_fill_give_every_item_its_own_result_in_order() {
        for threads in [1, 2, 3] {
            let workers = Workers::new(threads);
            let items: Vec<u64> = (0..23).collect();
            let (mut a, mut b) = (vec![0; 23], vec![0; 23]);
            workers.each(&items, &mut a, |x| x * x + 1);
            workers.fill(&items, &mut b, |x| x * x + 1);
            let want: Vec<u64> = items.iter().map(|x| x * x + 1).collect();
            assert_eq!((a, b), (want.clone(), want), "{threads} threads");
        }
    }
}
