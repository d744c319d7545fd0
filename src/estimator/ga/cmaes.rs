//! A small CMA-ES (covariance matrix adaptation evolution strategy, Hansen's
//! `(μ/μ_w, λ)` form with rank-one and rank-μ updates and cumulative step-size
//! adaptation) for the local polish of a hypothesis. The fitness of the texture terms
//! has narrow ridges along coupled genes (a tilt with a change of size); an isotropic
//! mutation crosses them only by chance, the adapted covariance follows them.

use nalgebra::{DMatrix, DVector, SymmetricEigen};
use rand::Rng;

use super::{normal, Genes, Problem, GENES};
use crate::estimator::fitness::Fitness;

/// Maximises `Fitness::score` of `problem` on `level` from
/// `start` with initial step `sigma` (normalised genes) for about `budget`
/// evaluations; returns the best seen and its fitness.
pub fn maximise(
    problem: &Problem,
    level: usize,
    start: Genes,
    sigma: f64,
    budget: usize,
    rng: &mut impl Rng,
) -> (Genes, Fitness) {
    let n = GENES as f64;
    let lambda = 4 + (3.0 * n.ln()).floor() as usize;
    let mu = lambda / 2;
    let raw: Vec<f64> = (0..mu)
        .map(|i| (mu as f64 + 0.5).ln() - ((i + 1) as f64).ln())
        .collect();
    let sum: f64 = raw.iter().sum();
    let w: Vec<f64> = raw.iter().map(|v| v / sum).collect();
    let mueff = 1.0 / w.iter().map(|v| v * v).sum::<f64>();
    let cc = (4.0 + mueff / n) / (n + 4.0 + 2.0 * mueff / n);
    let cs = (mueff + 2.0) / (n + mueff + 5.0);
    let c1 = 2.0 / ((n + 1.3).powi(2) + mueff);
    let cmu = (1.0 - c1).min(2.0 * (mueff - 2.0 + 1.0 / mueff) / ((n + 2.0).powi(2) + mueff));
    let damps = 1.0 + 2.0 * (0.0f64).max(((mueff - 1.0) / (n + 1.0)).sqrt() - 1.0) + cs;
    let chi_n = n.sqrt() * (1.0 - 1.0 / (4.0 * n) + 1.0 / (21.0 * n * n));

    let mut mean = DVector::from_column_slice(&start);
    let mut sigma = sigma;
    let (mut pc, mut ps) = (DVector::zeros(GENES), DVector::zeros(GENES));
    let mut c = DMatrix::<f64>::identity(GENES, GENES);
    let mut best = (start, problem.evaluate(level, &start));
    let mut used = 1;
    let mut kids = vec![[0.0; GENES]; lambda];
    let mut fit = vec![Fitness::default(); lambda];
    while used + lambda <= budget {
        let eig = SymmetricEigen::new(c.clone());
        let d = eig.eigenvalues.map(|v| v.max(1e-20).sqrt());
        let b = eig.eigenvectors;
        for k in kids.iter_mut() {
            let u = DVector::from_fn(GENES, |_, _| normal(rng));
            let z = &b * u.component_mul(&d);
            for i in 0..GENES {
                k[i] = (mean[i] + sigma * z[i]).clamp(0.0, 1.0);
            }
        }
        problem.evaluate_batch(level, &kids, &mut fit);
        used += lambda;
        let mut order: Vec<usize> = (0..lambda).collect();
        order.sort_by(|&a, &b| fit[b].score.total_cmp(&fit[a].score));
        if fit[order[0]].score > best.1.score {
            best = (kids[order[0]], fit[order[0]]);
        }
        // Steps actually taken (after clamping), in units of sigma.
        let ys: Vec<DVector<f64>> = order
            .iter()
            .take(mu)
            .map(|&i| (DVector::from_column_slice(&kids[i]) - &mean) / sigma)
            .collect();
        let yw: DVector<f64> = ys.iter().zip(&w).map(|(v, wi)| v * *wi).sum();
        mean += &yw * sigma;
        let inv_sqrt = &b * DMatrix::from_diagonal(&d.map(|v| 1.0 / v)) * b.transpose();
        ps = &ps * (1.0 - cs) + &inv_sqrt * &yw * (cs * (2.0 - cs) * mueff).sqrt();
        let hsig =
            ps.norm() / (1.0 - (1.0 - cs).powi(2 * (used / lambda) as i32)).sqrt() / chi_n < 1.4 + 2.0 / (n + 1.0);
        pc = &pc * (1.0 - cc) + &yw * (if hsig { (cc * (2.0 - cc) * mueff).sqrt() } else { 0.0 });
        let rank_mu: DMatrix<f64> = ys.iter().zip(&w).map(|(v, wi)| v * v.transpose() * *wi).sum();
        c = &c * (1.0 - c1 - cmu) + (&pc * pc.transpose()) * c1 + rank_mu * cmu;
        sigma *= ((cs / damps) * (ps.norm() / chi_n - 1.0)).exp();
        sigma = sigma.clamp(1e-5, 0.3);
    }
    best
}
