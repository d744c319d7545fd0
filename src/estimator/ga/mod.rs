//! The genetic algorithm over Φ = (x, y, z, ε1, ε2, ε3, α, k) (paper §4).
//!
//! Genes live in `[0, 1]` and are decoded through the [`Bounds`] of the search space.
//! [`paper`] is the literal binary GA; [`robust`] the default coarse-to-fine search,
//! seeded by the exhaustive [`scan`]. Both evaluate only new individuals, in parallel,
//! from a seeded RNG. Tracking keeps a [`live::LivePopulation`] from frame to frame.

pub mod cmaes;
pub mod compass;
pub mod live;
pub mod observe;
pub mod paper;
pub mod polish;
pub mod quick;
pub mod relocate;
pub mod robust;
pub mod scan;

use nalgebra::Vector3;
use robust::normal;

use crate::estimator::fitness::{Fitness, PointSet, Scorer};
use crate::estimator::model::PhotoModel;
use crate::estimator::pose::PoseSize;
use crate::estimator::settings::SearchSpace;
use crate::estimator::verify::plane::TwoEyes;
use crate::estimator::verify::texture::{self, Texture};
use crate::estimator::verify::{TextureTerm, Verdict};
use crate::estimator::workers::Workers;
use crate::vision::lookup::LevelLookup;

/// Number of genes in a chromosome.
pub const GENES: usize = 8;
/// Normalised genes, each in `[0, 1]`.
pub type Genes = [f64; GENES];

/// Maps normalised genes to physical values: x, y, z in mm, ε in [−1, 1], α from the
/// size range (`α = L_P / L`), k from the aspect range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounds {
    /// The values of genes at 0.
    pub lo: Genes,
    /// The values of genes at 1.
    pub hi: Genes,
    /// Decode α geometrically (uniform in log size) instead of linearly.
    pub log_alpha: bool,
    /// How far the position genes may go beyond 0–1, as a share of their range on
    /// either side: 0 for a search, [`TrackingSettings::reach`] for the tracker, which
    /// follows an object it acquired beyond the space it searches.
    ///
    /// [`TrackingSettings::reach`]: crate::estimator::settings::TrackingSettings::reach
    pub reach: f64,
    /// The ranges (low, high) of the genes of α and k instead of 0–1, where a tracked
    /// object's size is held ([`Bounds::holding_size`]).
    pub held_size: Option<[[f64; 2]; 2]>,
}

impl Bounds {
    /// The bounds of `search` for `model` (α from its length `L_P` and the size range);
    /// `log_alpha` as in [`Bounds::log_alpha`].
    pub fn new(search: &SearchSpace, model: &PhotoModel, log_alpha: bool) -> Self {
        let alpha = [model.l_p / search.size_mm[1], model.l_p / search.size_mm[0]];
        let lo = [
            search.x_mm[0],
            search.y_mm[0],
            search.z_mm[0],
            -1.0,
            -1.0,
            -1.0,
            alpha[0],
            search.aspect_k[0],
        ];
        let hi = [
            search.x_mm[1],
            search.y_mm[1],
            search.z_mm[1],
            1.0,
            1.0,
            1.0,
            alpha[1],
            search.aspect_k[1],
        ];
        Self {
            lo,
            hi,
            log_alpha,
            reach: 0.0,
            held_size: None,
        }
    }

    /// These bounds with the position genes reaching `reach` of their range beyond each
    /// end ([`Bounds::reach`]).
    pub fn reaching(self, reach: f64) -> Self {
        Self { reach, ..self }
    }

    /// These bounds with α and k held within `share` on either side of those whose genes
    /// are `size` ([`Bounds::held_size`]).
    pub fn holding_size(self, size: [f64; 2], share: f64) -> Self {
        let mut g = [0.5; GENES];
        (g[6], g[7]) = (size[0], size[1]);
        let p = self.decode(&g);
        let genes = |f: f64| {
            self.unclamped(&PoseSize {
                alpha: p.alpha * f,
                k: p.k * f,
                ..p
            })
        };
        let (lo, hi) = (genes(1.0 / (1.0 + share)), genes(1.0 + share));
        Self {
            held_size: Some([[lo[6], hi[6]], [lo[7], hi[7]]]),
            ..self
        }
    }

    /// Gene `i` of value `v` brought into the bounds: 0–1, for a position gene
    /// `[-reach, 1 + reach]`, for a held size gene its range within 0–1.
    pub fn clamp(&self, i: usize, v: f64) -> f64 {
        if let Some(held) = self.held_size.filter(|_| i >= 6) {
            let [lo, hi] = held[i - 6];
            return v.clamp(lo.max(0.0), hi.min(1.0));
        }
        let r = if i < 3 { self.reach } else { 0.0 };
        // 0.0 − r, not −r: a search's genes clamp to +0.0, as they always have.
        v.clamp(0.0 - r, 1.0 + r)
    }

    /// The pose and size that genes `g` stand for.
    pub fn decode(&self, g: &Genes) -> PoseSize {
        let lin = |i: usize| self.lo[i] + g[i] * (self.hi[i] - self.lo[i]);
        let alpha = if self.log_alpha {
            self.lo[6] * (self.hi[6] / self.lo[6]).powf(g[6])
        } else {
            lin(6)
        };
        PoseSize {
            position: Vector3::new(lin(0), lin(1), lin(2)),
            eps: Vector3::new(lin(3), lin(4), lin(5)),
            alpha,
            k: lin(7),
        }
    }

    /// Inverse of [`Bounds::decode`] (clamped into the bounds, [`Bounds::clamp`]).
    pub fn encode(&self, p: &PoseSize) -> Genes {
        self.clamped(&self.unclamped(p))
    }

    /// Genes `g` brought into the bounds ([`Bounds::clamp`]).
    pub fn clamped(&self, g: &Genes) -> Genes {
        std::array::from_fn(|i| self.clamp(i, g[i]))
    }

    /// Whether `p` lies in the search space (its genes in 0–1).
    pub fn contains(&self, p: &PoseSize) -> bool {
        self.unclamped(p).iter().all(|g| (0.0..=1.0).contains(g))
    }

    /// The genes of `p`, outside 0–1 where it is outside the search space.
    fn unclamped(&self, p: &PoseSize) -> Genes {
        let vals = [
            p.position.x,
            p.position.y,
            p.position.z,
            p.eps.x,
            p.eps.y,
            p.eps.z,
            p.alpha,
            p.k,
        ];
        let mut g = [0.0; GENES];
        for i in 0..GENES {
            g[i] = if i == 6 && self.log_alpha {
                (vals[i] / self.lo[i]).ln() / (self.hi[i] / self.lo[i]).ln()
            } else {
                (vals[i] - self.lo[i]) / (self.hi[i] - self.lo[i])
            };
        }
        g
    }
}

/// One frame's search problem: the scorer, the frame's lookup images at every pyramid
/// level and the model's points at each level.
pub struct Problem<'a> {
    /// The fitness of the model.
    pub scorer: &'a Scorer,
    /// Level 0 at full resolution.
    pub levels: &'a [LevelLookup],
    /// Points used on each pyramid level (coarser levels use a sub-grid).
    pub points: &'a [PointSet],
    /// The search space.
    pub bounds: Bounds,
    /// The threads that evaluate candidates.
    pub workers: Workers,
    /// The texture terms, where the frame has them (robust mode).
    pub texture: Option<TextureTerm<'a>>,
    /// Told each generation's best individual, when set (see [`observe`]).
    pub observer: Option<observe::Observer<'a>>,
    /// The acquisition scan tries each placement tilted by this angle (radians) about
    /// the model's x and about its y axis instead of facing the camera; 0: facing (see
    /// [`scan`]).
    pub scan_tilt: f64,
    /// The acquisition scan runs on a finer grid of sizes and rolls and ranks its first
    /// pass by the structure term as well as by colour (see [`scan`]): slower, for a
    /// retry where the colours of the wall match the card's.
    pub scan_dense: bool,
    /// The acquisition scan tries only small apparent sizes (see [`scan`]): for a scan
    /// on a level finer than the pyramid's coarsest, which sees the larger ones well.
    pub scan_small_only: bool,
}

impl<'a> Problem<'a> {
    /// The problem, evaluated on `threads` threads (0: one per core).
    pub fn new(
        scorer: &'a Scorer,
        levels: &'a [LevelLookup],
        points: &'a [PointSet],
        bounds: Bounds,
        threads: usize,
    ) -> Self {
        Self {
            scorer,
            levels,
            points,
            bounds,
            workers: Workers::new(threads),
            texture: None,
            observer: None,
            scan_tilt: 0.0,
            scan_dense: false,
            scan_small_only: false,
        }
    }

    /// The same problem evaluated on the calling thread alone: for work that runs
    /// several searches side by side, one per worker.
    pub fn serial(&self) -> Problem<'a> {
        Problem {
            workers: Workers::new(1),
            ..*self
        }
    }

    /// The problem with the texture terms in its ranking.
    pub fn with_texture(self, texture: TextureTerm<'a>) -> Self {
        Self {
            texture: Some(texture),
            ..self
        }
    }

    /// Fitness of one candidate on level `l`: the colour fitness, and on levels finer
    /// than [`TextureTerm::below_level`] the weighted texture terms in its score.
    pub fn evaluate(&self, l: usize, g: &Genes) -> Fitness {
        let l = l.min(self.levels.len() - 1);
        let c = self.bounds.decode(g);
        let mut f = self.scorer.evaluate(&self.points[l], &self.levels[l], &c);
        if let Some(t) = self.texture.as_ref().filter(|t| l < t.below_level) {
            if f != Fitness::default() {
                f.score += t.weight * self.texture_at(l, &t.points[l], &c).sum();
            }
        }
        f
    }

    /// The texture terms of candidate `c` on level `l` with `points` (zero without a
    /// texture term).
    pub fn texture_at(&self, l: usize, points: &PointSet, c: &PoseSize) -> Texture {
        let Some(t) = &self.texture else {
            return Texture::default();
        };
        self.terms_on(t, l, points, c, false, t.brightness_where_flat)
    }

    /// The texture terms at candidate `c` on full resolution, denoised, on the detail
    /// alone, as the verdict reads them (zero without a texture term). A tracking
    /// frame's status reads them so although its ranking may read the brightness where
    /// the detail is flat ([`TextureTerm::brightness_where_flat`]): judged on the
    /// brightness too, the card at 1200 mm/s (the 60 fps play of the sweep) had 116–120
    /// `tracking` poses more than 50 mm or 20° off in 25 s, against 2–11 so.
    pub fn texture_judged(&self, c: &PoseSize) -> Texture {
        let Some(t) = &self.texture else {
            return Texture::default();
        };
        self.terms_on(t, 0, &t.points[0], c, true, false)
    }

    /// The stereo term at candidate `c` on full resolution without the points where the
    /// eyes disagree far more than at most ([`TwoEyes::trimmed_detail_agreement`]); zero
    /// without a texture term.
    pub fn stereo_trimmed_judged(&self, c: &PoseSize) -> f64 {
        let Some(t) = &self.texture else {
            return 0.0;
        };
        let two = TwoEyes {
            points: &t.points[0],
            rig: &self.levels[0].rig,
            eyes: t.pyramid.eyes(0),
            left_from_hand: &self.scorer.left_from_hand,
        };
        two.trimmed_detail_agreement(c)
    }

    /// [`texture::score`] of `c` on level `l` with `points`, read `denoised` and, with
    /// `brightness_where_flat`, on the brightness where the detail is flat.
    fn terms_on(
        &self,
        t: &TextureTerm,
        l: usize,
        points: &PointSet,
        c: &PoseSize,
        denoised: bool,
        brightness_where_flat: bool,
    ) -> Texture {
        let l = l.min(self.levels.len() - 1);
        texture::score(
            points,
            &self.levels[l].rig,
            t.pyramid.eyes(l),
            &self.scorer.left_from_hand,
            c,
            texture::Reading {
                denoised,
                partial_view: self.scorer.partial_view,
                brightness_where_flat,
            },
        )
    }

    /// Fitness of many candidates on level `l`, split across the worker threads.
    pub fn evaluate_batch(&self, l: usize, genes: &[Genes], out: &mut [Fitness]) {
        self.par_fill(genes, out, |g| self.evaluate(l, g));
    }

    /// `out[i] = f(&items[i])` on the worker threads.
    pub fn par_fill<T: Sync, R: Send>(&self, items: &[T], out: &mut [R], f: impl Fn(&T) -> R + Sync) {
        self.workers.fill(items, out, f)
    }
}

/// The model's points for `levels` pyramid levels; with `thin`, coarse level `l` uses
/// the model as a thumbnail: one point per `2^l` × `2^l` block.
pub fn level_points(model: &PhotoModel, scorer: &Scorer, levels: usize, thin: bool) -> Vec<PointSet> {
    (0..levels)
        .map(|l| PointSet::from_model(model, &scorer.params, if thin { 1 << l } else { 1 }))
        .collect()
}

/// The best individual at one generation (for the paper's Table 2).
#[derive(Debug, Clone, Copy)]
pub struct Snapshot {
    /// Generations run when it was taken.
    pub generation: usize,
    /// The best individual's pose and size.
    pub best: PoseSize,
    /// Fitness at full resolution.
    pub fitness: Fitness,
}

/// Result of a one-shot estimate.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// The estimate: the best individual's pose and size.
    pub best: PoseSize,
    /// Its fitness at full resolution.
    pub fitness: Fitness,
    /// Generations run per search.
    pub generations: usize,
    /// Searches run: more than one when a robust search found nothing and ran again.
    pub searches: usize,
    /// Candidates evaluated, on any pyramid level, in all searches.
    pub evaluations: usize,
    /// The best individual at each of the [`snapshot_generations`].
    pub snapshots: Vec<Snapshot>,
    /// Whether the object is judged found at `best`, and how sure.
    pub verdict: Verdict,
}

/// Generations at which the best individual is reported: 100, 500 and the last.
pub fn snapshot_generations(total: usize) -> Vec<usize> {
    let mut v: Vec<usize> = [100, 500].into_iter().filter(|&g| g < total).collect();
    v.push(total);
    v
}

/// Which of several equally scored individuals [`best_index`] takes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ties {
    /// The first: in a population sorted best first, a survivor over a child that only
    /// equals it (the robust search).
    First,
    /// The last, as [`Iterator::max_by`] takes it: a child over the survivor it equals
    /// (the paper's GA and tracking). Each search keeps the rule it was tuned with, so
    /// that a seed gives the results it always gave.
    Last,
}

/// Index of the highest [`Fitness::score`] (compared with [`f64::total_cmp`]), of equal
/// ones the one `ties` names; 0 for no individuals.
pub fn best_index(fitness: &[Fitness], ties: Ties) -> usize {
    let mut best = 0;
    for (i, f) in fitness.iter().enumerate().skip(1) {
        let order = f.score.total_cmp(&fitness[best].score);
        if order.is_gt() || (ties == Ties::Last && order.is_eq()) {
            best = i;
        }
    }
    best
}

/// Indices of `fitness` sorted best first (NaN-safe).
pub(crate) fn rank(fitness: &[Fitness], order: &mut Vec<usize>) {
    order.clear();
    order.extend(0..fitness.len());
    order.sort_by(|&a, &b| fitness[b].score.total_cmp(&fitness[a].score));
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimator::model::{InnerPoint, PixelBox};

    fn model() -> PhotoModel {
        PhotoModel {
            format: "photopose-model".into(),
            version: 1,
            photo: "p".into(),
            bbox: PixelBox {
                x: 0,
                y: 0,
                w: 200,
                h: 100,
            },
            l_p: 200.0,
            b_p: 100.0,
            step_px: 10.0,
            outer_width_px: 10.0,
            mean_hue: 0.0,
            mean_saturation: 0.0,
            center_class: "chromatic".into(),
            inner: vec![InnerPoint {
                x: 0.0,
                y: 0.0,
                h: 0,
                s: 0,
                v: 0,
            }],
            outer: vec![],
            detection: None,
        }
    }

    #[test]
    fn best_index_takes_the_highest_score_and_breaks_ties_as_told() {
        let fit = |scores: &[f64]| -> Vec<Fitness> {
            scores
                .iter()
                .map(|&score| Fitness {
                    score,
                    ..Fitness::default()
                })
                .collect()
        };
        let scores = fit(&[0.5, 1.5, 0.2, 1.5, 1.0]);
        assert_eq!(best_index(&scores, Ties::First), 1);
        assert_eq!(best_index(&scores, Ties::Last), 3);
        assert_eq!(best_index(&fit(&[2.0, 1.0]), Ties::Last), 0);
        assert_eq!(best_index(&[], Ties::First), 0);
        // The same choice as the best-first order of `rank`, and as `Iterator::max_by`.
        let mut order = Vec::new();
        rank(&scores, &mut order);
        assert_eq!(order[0], best_index(&scores, Ties::First));
        let last = (0..scores.len()).max_by(|&a, &b| scores[a].score.total_cmp(&scores[b].score));
        assert_eq!(last, Some(best_index(&scores, Ties::Last)));
    }

    #[test]
    fn bounds_decode_and_encode_round_trip() {
        let search = SearchSpace {
            x_mm: [-300.0, 300.0],
            y_mm: [-300.0, 300.0],
            z_mm: [300.0, 1200.0],
            size_mm: [20.0, 400.0],
            aspect_k: [0.5, 2.0],
        };
        for log_alpha in [false, true] {
            let b = Bounds::new(&search, &model(), log_alpha);
            let lo = b.decode(&[0.0; GENES]);
            let hi = b.decode(&[1.0; GENES]);
            assert_eq!(lo.position.z, 300.0);
            assert_eq!(hi.position.z, 1200.0);
            // α from L range: L = 400 → α = 0.5, L = 20 → α = 10.
            assert!((lo.alpha - 0.5).abs() < 1e-12 && (hi.alpha - 10.0).abs() < 1e-12);
            let g = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8];
            let back = b.encode(&b.decode(&g));
            for i in 0..GENES {
                assert!((back[i] - g[i]).abs() < 1e-12);
            }
        }
        assert_eq!(snapshot_generations(1000), vec![100, 500, 1000]);
        assert_eq!(snapshot_generations(300), vec![100, 300]);
    }
}
