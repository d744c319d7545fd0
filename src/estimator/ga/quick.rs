//! The quick first pass of an acquisition: the acquisition scan's distinct regions,
//! each climbed level by level up to full resolution as a relocation climbs its
//! placements, without the GA. Where the verdict finds its best, the tracker's
//! acquisition ends there, in about 45 % of the time of its search (300 generations,
//! the scan included in both). Where not, it ends there as well if the result's size
//! is settled ([`size_settled`]) and the last acquisition did not end at an unfound
//! quick pass; otherwise the search runs from the same scan.

use super::relocate::climbed_level_by_level;
use super::scan::Scanned;
use super::{compass, polish, Genes, Problem};
use crate::estimator::fitness::Fitness;

/// Distinct scan regions climbed, chosen as the search's hypotheses are
/// ([`polish::distinct`]: 40 mm apart, at most 2 per octave of apparent size).
const STARTS: usize = 9;

/// Evaluations of each region's climb per level.
const CLIMB: usize = 1000;

/// The best of the scan's distinct regions, each climbed level by level.
pub fn quick(problem: &Problem, scan: &Scanned) -> Option<(Genes, Fitness)> {
    let starts = polish::distinct(problem, &scan.regions, STARTS, 40.0, STARTS / 4);
    (!starts.is_empty()).then(|| climbed_level_by_level(problem, starts, None, CLIMB))
}

/// Relative change of length or breadth within which [`size_settled`] calls a size
/// settled.
const SETTLED: f64 = 0.1;

/// Whether the score's peak in size lies near `g`'s: its length and breadth change by
/// less than 10 % (`SETTLED`) under two size sweeps at full resolution
/// ([`compass::sweep_sizes`]). A quick result on part of its target (the rocket
/// card's 180 mm length found 125 mm long, on the photo's sky) grows there.
pub fn size_settled(problem: &Problem, g: &Genes) -> bool {
    let swept = (0..2).fold(*g, |h, _| compass::sweep_sizes(problem, 0, h).0);
    let [l, b] = problem.scorer.box_px;
    let [before, after] = [g, &swept].map(|x| problem.bounds.decode(x).size_mm(l, b));
    (0..2).all(|i| (after[i] / before[i]).ln().abs() < (1.0 + SETTLED).ln())
}
