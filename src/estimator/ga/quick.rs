//! The quick first pass of an acquisition: the acquisition scan's distinct regions,
//! each climbed level by level up to full resolution as a relocation climbs its
//! placements, without the GA. Where the verdict finds its best, the tracker's
//! acquisition ends there, in about 45 % of the time of its search (300 generations,
//! the scan included in both); where not, the search runs from the same scan.

use super::relocate::climbed_level_by_level;
use super::scan::Scanned;
use super::{polish, Genes, Problem};
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
