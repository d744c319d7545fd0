//! The paper's GA taken literally: 8 genes × 10 bits, sort, keep the best, replace the
//! weak by single-point crossover and bit-flip mutation of the survivors, evaluate only
//! the new individuals, at full resolution.

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use super::{best_index, rank, snapshot_generations, Genes, Outcome, Problem, Snapshot, Ties, GENES};
use crate::estimator::fitness::Fitness;
use crate::estimator::settings::GaSettings;

/// Bits per gene.
pub const BITS: u32 = 10;
const MAX: u16 = (1 << BITS) - 1;

/// A binary chromosome: one 10-bit integer per gene.
pub type Chromosome = [u16; GENES];

/// Normalised genes of a chromosome.
pub fn genes(c: &Chromosome) -> Genes {
    c.map(|v| v as f64 / MAX as f64)
}

/// Single-point crossover over the 80-bit string: bits before `cut` from `a`, the rest from `b`.
pub fn crossover(a: &Chromosome, b: &Chromosome, cut: u32) -> Chromosome {
    let mut child = *a;
    for (i, gene) in child.iter_mut().enumerate() {
        let start = i as u32 * BITS;
        if cut <= start {
            *gene = b[i];
        } else if cut < start + BITS {
            // The high (first) bits up to the cut come from a.
            let from_a = cut - start;
            let mask_b = (1u16 << (BITS - from_a)) - 1;
            *gene = (a[i] & !mask_b & MAX) | (b[i] & mask_b);
        }
    }
    child
}

/// Flips each bit with probability `rate`.
pub fn mutate(c: &mut Chromosome, rate: f64, rng: &mut impl Rng) {
    for gene in c.iter_mut() {
        for bit in 0..BITS {
            if rng.random::<f64>() < rate {
                *gene ^= 1 << bit;
            }
        }
    }
}

/// Runs `generations` generations of the binary GA on full-resolution images.
pub fn run(
    problem: &Problem,
    ga: &GaSettings,
    generations: usize,
    seed: u64,
    progress: &mut dyn FnMut(usize),
) -> Outcome {
    let mut rng = StdRng::seed_from_u64(seed);
    let n = ga.population;
    let keep = ga.survivor_count();
    let mut pop: Vec<Chromosome> = (0..n)
        .map(|_| std::array::from_fn(|_| rng.random_range(0..=MAX)))
        .collect();
    let mut gen_buf: Vec<Genes> = pop.iter().map(genes).collect();
    let mut fit = vec![Fitness::default(); n];
    problem.evaluate_batch(0, &gen_buf, &mut fit);
    let mut evaluations = n;
    let mut order = Vec::with_capacity(n);
    let marks = snapshot_generations(generations);
    let mut snapshots = Vec::new();
    for generation in 1..=generations {
        rank(&fit, &mut order);
        let sorted_pop: Vec<Chromosome> = order.iter().map(|&i| pop[i]).collect();
        let sorted_fit: Vec<Fitness> = order.iter().map(|&i| fit[i]).collect();
        pop = sorted_pop;
        fit = sorted_fit;
        for i in keep..n {
            let a = pop[rng.random_range(0..keep)];
            let mut child = if rng.random::<f64>() < ga.crossover_rate {
                let b = pop[rng.random_range(0..keep)];
                crossover(&a, &b, rng.random_range(1..GENES as u32 * BITS))
            } else {
                a
            };
            mutate(&mut child, ga.bit_mutation_rate, &mut rng);
            pop[i] = child;
        }
        gen_buf.clear();
        gen_buf.extend(pop[keep..].iter().map(genes));
        problem.evaluate_batch(0, &gen_buf, &mut fit[keep..]);
        evaluations += n - keep;
        if marks.contains(&generation) {
            let best = best_index(&fit, Ties::Last);
            snapshots.push(Snapshot {
                generation,
                best: problem.bounds.decode(&genes(&pop[best])),
                fitness: fit[best],
            });
        }
        progress(generation);
        problem.observe(generation, 0, || genes(&pop[best_index(&fit, Ties::Last)]));
    }
    let best = best_index(&fit, Ties::Last);
    Outcome {
        best: problem.bounds.decode(&genes(&pop[best])),
        fitness: fit[best],
        generations,
        searches: 1,
        evaluations,
        snapshots,
        verdict: Default::default(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crossover_takes_bits_before_the_cut_from_the_first_parent() {
        let a = [MAX; GENES];
        let b = [0; GENES];
        let c = crossover(&a, &b, 13);
        assert_eq!(c[0], MAX);
        assert_eq!(c[1], 0b11_1000_0000);
        assert!(c[2..].iter().all(|&g| g == 0));
        assert_eq!(crossover(&a, &b, 80), a);
        assert_eq!(crossover(&a, &b, 0), b);
    }

    #[test]
    fn mutation_rate_controls_flips() {
        let mut rng = StdRng::seed_from_u64(3);
        let mut c = [0u16; GENES];
        mutate(&mut c, 0.0, &mut rng);
        assert_eq!(c, [0; GENES]);
        mutate(&mut c, 1.0, &mut rng);
        assert_eq!(c, [MAX; GENES]);
        let mut c = [0u16; GENES];
        let mut flips = 0;
        for _ in 0..100 {
            mutate(&mut c, 0.05, &mut rng);
            flips += c.iter().map(|g| g.count_ones()).sum::<u32>();
            c = [0; GENES];
        }
        // 100 × 80 bits × 5 % = 400 expected.
        assert!((300..500).contains(&flips), "{flips}");
        assert_eq!(genes(&[MAX; GENES]), [1.0; GENES]);
    }
}
