//! Acquisition by exhaustive scan on the coarsest pyramid level: the model, facing the
//! left camera (or, where [`Problem::scan_tilt`] is set, tilted about its own axes), is
//! slid over the left image at every few pixels, apparent sizes and in-plane
//! rotations (`F_L` only); the best distinct placements then get their depth from a
//! scan along the line of sight scored on both images. The results seed the GA.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use super::{Genes, Problem};
use crate::estimator::fitness::PointSet;
use crate::estimator::pose::PoseSize;
use crate::estimator::verify::texture;
use crate::vision::lookup::LevelLookup;

/// Pixel step of the position scan on the coarsest level.
const STEP_PX: f64 = 3.0;
/// Apparent sizes (model length in full-resolution pixels), log-spaced from the
/// smallest allowed extent to [`LARGEST_FRACTION`] of the image's height: with the
/// default 24 px, consecutive sizes 1.51 times apart on HD and 1.60 on FHD, or 1.30
/// and 1.35 in a dense scan ([`Problem::scan_dense`]).
const SIZES: usize = 8;
const DENSE_SIZES: usize = 12;
const LARGEST_FRACTION: f64 = 0.6;
/// The largest apparent size (full-resolution pixels) a scan of small sizes only tries
/// ([`Problem::scan_small_only`]): 32 px on a quarter-resolution level.
const SMALL_PX: f64 = 128.0;
/// In-plane rotations, evenly spaced over the full turn: 45° apart, or 22.5° in a dense
/// scan.
const ROLLS: usize = 8;
const DENSE_ROLLS: usize = 16;
/// The first pass scores every placement with one point in `SPARSE`; the `RESCORE` best
/// are then scored with every point.
const SPARSE: usize = 4;
const RESCORE: usize = 32768;
/// Distinct placements kept for the depth scan, and depths tried for each.
const KEEP: usize = 96;
const DEPTHS: usize = 40;

/// A placement of the model facing the left camera.
#[derive(Debug, Clone, Copy)]
struct Placement {
    u: f64,
    v: f64,
    /// Line of sight through `(u, v)` (z = 1), computed once per pixel.
    ray: Vector3<f64>,
    /// Model length over depth (`L / z`), i.e. apparent size over the focal length.
    l_over_z: f64,
    /// The model's rotation in the left camera's frame: an in-plane rotation (about the
    /// line of sight), possibly tilted about the model's own axes.
    roll: UnitQuaternion<f64>,
    /// Index of its apparent size, `0..` the grid's sizes.
    size: usize,
}

impl Placement {
    /// The candidate at depth `z`; `hand_from_left` is the inverse hand-eye transform.
    fn candidate(&self, problem: &Problem, hand_from_left: &Isometry3<f64>, z: f64) -> PoseSize {
        let left_from_model = Isometry3::from_parts(Translation3::from(self.ray * z), self.roll);
        let [l_p, b_p] = problem.scorer.box_px;
        let length = self.l_over_z * z;
        PoseSize::from_pose(
            &(hand_from_left * left_from_model),
            [length, length * b_p / l_p],
            l_p,
            b_p,
        )
    }
}

/// What the scan found: seeds for a population, and the regions it saw.
pub struct Scanned {
    /// Up to `n` candidates, best first (several may share a placement).
    pub seeds: Vec<Genes>,
    /// Each distinct placement at its best depth, best first.
    pub regions: Vec<Genes>,
}

/// The scan of the coarsest level: up to `n` seeds and every distinct region.
pub fn seeds(problem: &Problem, n: usize) -> Scanned {
    let scan = Scan::new(problem);
    let grid = scan.placements();
    let order = scan.best_placements(&grid);
    let kept = distinct(&grid, &order);
    scan.depth_scan(&kept, n)
}

/// Every placement of the scan, by index: each pixel at each apparent size and
/// orientation, without storing them all (millions, with tilts).
struct Grid {
    /// Pixel `(u, v)` and its line of sight.
    pixels: Vec<(f64, f64, Vector3<f64>)>,
    /// Apparent sizes (`L / z`), smallest first.
    sizes: Vec<f64>,
    orientations: Vec<UnitQuaternion<f64>>,
}

impl Grid {
    fn len(&self) -> usize {
        self.pixels.len() * self.sizes.len() * self.orientations.len()
    }

    /// Placement `i`: pixels vary fastest, then orientations, then sizes.
    fn get(&self, i: usize) -> Placement {
        let (np, no) = (self.pixels.len(), self.orientations.len());
        let (u, v, ray) = self.pixels[i % np];
        let size = i / (np * no);
        Placement {
            u,
            v,
            ray,
            l_over_z: self.sizes[size],
            roll: self.orientations[(i / np) % no],
            size,
        }
    }
}

/// The scan's view of the problem: the coarsest level and its points, and the fixed
/// depth at which placements are first compared.
struct Scan<'p, 'a> {
    problem: &'p Problem<'a>,
    level: &'p LevelLookup,
    points: &'p PointSet,
    hand_from_left: Isometry3<f64>,
    /// The geometric middle of the depth range.
    z_ref: f64,
}

impl Scan<'_, '_> {
    /// The scan's score of a placement's candidate `c` with `points` in the left image:
    /// `F_L` plus the weighted structure term there.
    fn left_score(&self, points: &PointSet, c: &PoseSize) -> f64 {
        let (problem, lv) = (self.problem, self.level);
        let f = problem.scorer.evaluate_left(points, lv, c);
        match &problem.texture {
            Some(t) => {
                let eye = t.pyramid.eyes(problem.levels.len() - 1)[0];
                let left_from_hand = &problem.scorer.left_from_hand;
                f + 2.0
                    * t.weight
                    * texture::structure_in(
                        points,
                        &lv.rig.left,
                        eye,
                        left_from_hand,
                        c,
                        problem.scorer.partial_view,
                    )
            }
            None => f,
        }
    }

    /// The depth scan's score of candidate `c`: the search's score on the coarsest
    /// level, with the texture terms if the problem has them.
    fn stereo_score(&self, c: &PoseSize) -> f64 {
        let problem = self.problem;
        let l = problem.levels.len() - 1;
        let f = problem.scorer.evaluate(self.points, self.level, c).score;
        match &problem.texture {
            Some(t) if f != 0.0 => f + t.weight * problem.texture_at(l, self.points, c).sum(),
            _ => f,
        }
    }
}

impl<'p, 'a> Scan<'p, 'a> {
    fn new(problem: &'p Problem<'a>) -> Self {
        let level = problem.levels.len() - 1;
        let b = &problem.bounds;
        Self {
            problem,
            level: &problem.levels[level],
            points: &problem.points[level],
            hand_from_left: problem.scorer.left_from_hand.inverse(),
            z_ref: (b.lo[2] * b.hi[2]).sqrt(),
        }
    }

    /// The candidate of `placement` at depth `z`.
    fn candidate(&self, placement: &Placement, z: f64) -> PoseSize {
        placement.candidate(self.problem, &self.hand_from_left, z)
    }

    /// Every placement: the left image's pixels every [`STEP_PX`], at [`SIZES`] apparent
    /// sizes from the smallest allowed extent to a large share of the image (those up
    /// to [`SMALL_PX`] only, where [`Problem::scan_small_only`]), and [`ROLLS`] in-plane
    /// rotations ([`DENSE_SIZES`] and [`DENSE_ROLLS`] in a dense scan), facing or tilted
    /// (see [`Scan::orientations`]).
    fn placements(&self) -> Grid {
        let (lv, problem) = (self.level, self.problem);
        let (w, h) = (lv.rig.width as f64, lv.rig.height as f64);
        let fx_full = lv.rig.left.fx / lv.scale;
        let smallest = problem.scorer.min_extent_px.max(16.0) / fx_full;
        let largest = LARGEST_FRACTION * (lv.rig.height as f64 / lv.scale) / fx_full;
        let sizes = if problem.scan_dense { DENSE_SIZES } else { SIZES };
        let mut pixels = Vec::new();
        let mut v = STEP_PX / 2.0;
        while v < h {
            let mut u = STEP_PX / 2.0;
            while u < w {
                pixels.push((u, v, lv.rig.left.ray(u, v)));
                u += STEP_PX;
            }
            v += STEP_PX;
        }
        Grid {
            pixels,
            sizes: (0..sizes)
                .map(|si| smallest * (largest / smallest).powf(si as f64 / (sizes - 1) as f64))
                .filter(|&s| !problem.scan_small_only || s * fx_full <= SMALL_PX)
                .collect(),
            orientations: self.orientations(),
        }
    }

    /// The in-plane rotations; where [`Problem::scan_tilt`] is set, each tilted by it
    /// about the model's x and about its y axis instead (a card tilted far from
    /// facing looks shorter along one side, and a facing model of either size misses
    /// it; the searches that scan tilted have had a facing scan before).
    fn orientations(&self) -> Vec<UnitQuaternion<f64>> {
        let tilt = self.problem.scan_tilt;
        let rolls = if self.problem.scan_dense { DENSE_ROLLS } else { ROLLS };
        let mut out = Vec::new();
        for ri in 0..rolls {
            let roll =
                UnitQuaternion::from_scaled_axis(Vector3::z() * (std::f64::consts::TAU * ri as f64 / rolls as f64));
            if tilt == 0.0 {
                out.push(roll);
            } else {
                out.extend([Vector3::x(), Vector3::y()].map(|a| roll * UnitQuaternion::from_scaled_axis(a * tilt)));
            }
        }
        out
    }

    /// Indices of the most promising placements, best first by `F_L` at the reference
    /// depth: a cheap pass with one point in [`SPARSE`], then every point for the
    /// [`RESCORE`] best of it. A dense scan adds the structure term to the cheap pass: on
    /// a wall of the card's colours `F_L` alone drops the card's placements there.
    fn best_placements(&self, grid: &Grid) -> Vec<usize> {
        let problem = self.problem;
        let sparse = self.points.every(SPARSE);
        let mut order: Vec<usize> = (0..grid.len()).collect();
        let mut rough = vec![0.0; grid.len()];
        problem.par_fill(&order, &mut rough, |&i| {
            let c = self.candidate(&grid.get(i), self.z_ref);
            if problem.scan_dense {
                self.left_score(&sparse, &c)
            } else {
                problem.scorer.evaluate_left(&sparse, self.level, &c)
            }
        });
        let promising = RESCORE.min(order.len());
        if promising < order.len() {
            order.select_nth_unstable_by(promising, |&a, &b| rough[b].total_cmp(&rough[a]));
            order.truncate(promising);
        }
        let mut exact = vec![0.0; order.len()];
        problem.par_fill(&order, &mut exact, |&i| {
            self.left_score(self.points, &self.candidate(&grid.get(i), self.z_ref))
        });
        let mut ranked: Vec<(usize, f64)> = order.into_iter().zip(exact).collect();
        ranked.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        ranked.into_iter().map(|(i, _)| i).collect()
    }

    /// The `n` best candidates of a scan along each placement's line of sight over the
    /// depth range, scored on both images.
    fn depth_scan(&self, kept: &[Placement], n: usize) -> Scanned {
        let (problem, b) = (self.problem, &self.problem.bounds);
        let depths: Vec<f64> = (0..DEPTHS)
            .map(|i| b.lo[2] * (b.hi[2] / b.lo[2]).powf(i as f64 / (DEPTHS - 1) as f64))
            .collect();
        let trials: Vec<(Placement, f64)> = kept.iter().flat_map(|p| depths.iter().map(move |&z| (*p, z))).collect();
        let mut fits = vec![0.0; trials.len()];
        problem.par_fill(&trials, &mut fits, |(pl, z)| self.stereo_score(&self.candidate(pl, *z)));
        let encode = |i: usize| {
            let (pl, z) = trials[i];
            b.encode(&self.candidate(&pl, z))
        };
        let mut order: Vec<usize> = (0..trials.len()).collect();
        order.sort_by(|&a, &b| fits[b].total_cmp(&fits[a]));
        // The best depth of each placement: the first of its trials in `order`.
        let mut seen = vec![false; kept.len()];
        let regions = order
            .iter()
            .filter(|&&i| !std::mem::replace(&mut seen[i / DEPTHS], true))
            .map(|&i| encode(i))
            .collect();
        Scanned {
            seeds: order.into_iter().take(n).map(encode).collect(),
            regions,
        }
    }
}

/// Up to [`KEEP`] placements in `order`, at most an equal share of each apparent size,
/// skipping any within a few pixels of a kept (better) one of similar size. Small
/// placements inside a target's uniform areas score high on the coarse grid of rolls
/// and sizes, where a target-sized one is slightly off; without the shares they crowd out
/// every larger size.
fn distinct(grid: &Grid, order: &[usize]) -> Vec<Placement> {
    let mut kept: Vec<Placement> = Vec::with_capacity(KEEP);
    let mut per_size = vec![0usize; grid.sizes.len()];
    for &i in order {
        let p = grid.get(i);
        if per_size[p.size] == KEEP / grid.sizes.len() {
            continue;
        }
        let near = kept.iter().any(|k| {
            let size_ratio = (p.l_over_z / k.l_over_z).ln().abs();
            (p.u - k.u).hypot(p.v - k.v) < 3.0 * STEP_PX && size_ratio < 0.5
        });
        if !near {
            kept.push(p);
            per_size[p.size] += 1;
            if kept.len() == KEEP {
                break;
            }
        }
    }
    kept
}
