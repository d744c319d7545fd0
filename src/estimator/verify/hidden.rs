//! A card partly hidden by something in front of it (a bar, a forearm). The colour
//! fitness rewards a model shrunk onto the visible part: its inner points all match,
//! and its outer strip on the occluder counts as background. But a shrunk model
//! squeezes the photo's texture: the photo lines up with the visible part of the image
//! only at the card's true extent. So each side of a result is grown in turn, and the
//! photo's brightness is correlated with the left eye's on the part the result covered
//! only; a side whose growth lines the photo up clearly better is grown, or both sides
//! of an axis about the centre. The grown model's edges and its roll are then climbed
//! in turn on the same correlation and on the brightness step across the model's
//! sides (its outline), after a scan of each side's and axis's extent; so are those of
//! every result where no side grows, found or not. (The right eye sees a nearer
//! occluder's edge shifted into that part, so the correlation does not read it.)

use nalgebra::Vector3;

use super::outline;
use super::plane::TwoEyes;
use super::texture::{both_eyes, Ncc};
use crate::estimator::fitness::PointSet;
use crate::estimator::pose::PoseSize;

/// Growth factors of a side tried first, up to ×2: half of the card hidden.
const GROWTH: [f64; 12] = [1.05, 1.1, 1.15, 1.2, 1.25, 1.3, 1.4, 1.5, 1.6, 1.7, 1.8, 2.0];

/// The least growth taken, and the least gain of the correlation for it: a model that
/// sits well on an unhidden card gains at most 0.013 by growing (on the random set).
const MIN_GROWTH: f64 = 1.02;
const MIN_GAIN: f64 = 0.025;

/// What may grow, and what the edge climb moves, as [`PoseSize::resized`] takes it:
/// along the length or the width, the edge at −½ or +½ moved (the other held), then
/// each axis about its centre (a photo smooth on both sides, like a rocket in the sky,
/// lets the search shrink the model about its centre).
const GROWTHS: [(bool, f64); 6] = [
    (true, -0.5),
    (true, 0.5),
    (false, -0.5),
    (false, 0.5),
    (true, 0.0),
    (false, 0.0),
];

/// `c` with up to two of its sides or axes (`GROWTHS`) grown where the photo's
/// texture lines up better with the part of the image that `c` covers (`box_px`: the
/// photo box, for sizes), then its edges and roll lined up on that alignment and the
/// outline (`lined_up`), whether a side grew or not: under blur, a colour cast and a
/// bar, a search can end long or short along one axis, where no side's growth gains
/// enough to be taken, and a found result as well (the random set's scene 347, the
/// rocket card under a bar: found 22 % short, 0.7 % lined up).
pub fn uncovered(two: &TwoEyes, c: &PoseSize, box_px: [f64; 2]) -> PoseSize {
    let mut best = *c;
    let mut at = alignment(two, c, c, box_px);
    let mut grown = [false; GROWTHS.len()];
    for _ in 0..2 {
        let tries = GROWTHS
            .iter()
            .enumerate()
            .filter(|(k, _)| !grown[*k])
            .map(|(k, &(length, side))| {
                let (f, a) = best_growth(two, c, &best, box_px, length, side);
                (k, f, a)
            });
        let Some((k, f, a)) = tries.max_by(|x, y| x.2.total_cmp(&y.2)) else {
            break;
        };
        if f < MIN_GROWTH || a < at + MIN_GAIN {
            break;
        }
        let (length, side) = GROWTHS[k];
        best = best.resized(box_px, length, f, side);
        at = a;
        grown[k] = true;
    }
    lined_up(two, c, best, box_px)
}

/// `q` with its edges (each side, and each axis about its centre) and its roll about its
/// normal climbed in turn while that lines the photo up better with `shown`'s part of
/// the image, its outline taken into account ([`outlined`]), up to [`ROUNDS`] times,
/// after a scan of each side's and axis's extent ([`scanned`]). A model shrunk onto the
/// part of the card a bar leaves visible often sits turned a few degrees as well; its
/// sides grown at that roll land the size 10–20 % off, and each climb alone stops where
/// the other's error holds it. A model short or long about its centre (both sides a few
/// millimetres in or out) needs both sides moved at once: one side at a time, scene 48
/// of the random set stayed 5.3 % short, 3.9 % with the axes.
fn lined_up(two: &TwoEyes, shown: &PoseSize, mut q: PoseSize, box_px: [f64; 2]) -> PoseSize {
    let mut at = outlined(two, shown, &q, box_px);
    let edges = |q: &PoseSize, step: f64| {
        GROWTHS
            .iter()
            .flat_map(|&(length, side)| [1.0 + step, 1.0 - step].map(|f| q.resized(box_px, length, f, side)))
            .collect()
    };
    let roll = |q: &PoseSize, step: f64| [step, -step].map(|a| q.turned(Vector3::z(), a)).to_vec();
    (q, at) = scanned(two, shown, (q, at), box_px);
    for _ in 0..ROUNDS {
        let edged = climbed(two, shown, (q, at), box_px, EDGE_STEPS, edges);
        let (next, a) = climbed(two, shown, edged, box_px, ROLL_STEPS_RAD, roll);
        let gained = a > at + 1e-4;
        (q, at) = (next, a);
        if !gained {
            break;
        }
    }
    q
}

/// `q` (at `at` on [`outlined`] for `shown`) with each side and each axis about its
/// centre (`GROWTHS`) in turn set to the best of the factors [`SCAN`] where that lines
/// the photo up better, and where it ends. The climbs stop on the first peak they meet:
/// a model a bar left 15–50 % short along one side grew back only part of the way (the
/// random set's scene 64, a bar over 22 % of the rocket card: 14.9 % short and 21° off
/// without the scan, 0.8 % and 1.0° with it).
fn scanned(two: &TwoEyes, shown: &PoseSize, (mut q, mut at): (PoseSize, f64), box_px: [f64; 2]) -> (PoseSize, f64) {
    let [least, most, step] = SCAN;
    let n = ((most - least) / step).round() as usize;
    for &(length, side) in &GROWTHS {
        let base = q;
        for i in 0..=n {
            let m = base.resized(box_px, length, least + step * i as f64, side);
            let o = outlined(two, shown, &m, box_px);
            if o > at {
                (q, at) = (m, o);
            }
        }
    }
    (q, at)
}

/// The factors [`scanned`] tries for each side and axis: from 0.9 to 1.5 in steps of 0.02.
const SCAN: [f64; 3] = [0.9, 1.5, 0.02];

/// Most rounds of [`lined_up`].
const ROUNDS: usize = 6;

/// The first and least steps of the edge climb (shares of a side) and of the roll
/// climb (radians: 4° down to 0.25°).
const EDGE_STEPS: [f64; 2] = [0.04, 0.005];
const ROLL_STEPS_RAD: [f64; 2] = [0.0698, 0.0043];

/// `q` (at `at` on [`outlined`] for `shown`) after a climb that takes the best of
/// `moves(q, step)` while that rises, halving the step from `steps[0]` to `steps[1]`
/// whenever none does; and where it ends on [`outlined`].
fn climbed(
    two: &TwoEyes,
    shown: &PoseSize,
    (mut q, mut at): (PoseSize, f64),
    box_px: [f64; 2],
    steps: [f64; 2],
    moves: impl Fn(&PoseSize, f64) -> Vec<PoseSize>,
) -> (PoseSize, f64) {
    let mut step = steps[0];
    while step >= steps[1] {
        let best = moves(&q, step)
            .into_iter()
            .map(|m| (outlined(two, shown, &m, box_px), m))
            .max_by(|x, y| x.0.total_cmp(&y.0))
            .expect("moves");
        if best.0 > at {
            (at, q) = best;
        } else {
            step /= 2.0;
        }
    }
    (q, at)
}

/// What [`lined_up`] climbs on: [`alignment`] plus [`OUTLINE_WEIGHT`] times the
/// brightness step across `q`'s sides ([`outline::contrast`]). The texture of a photo
/// smooth near its border (the rocket in its sky) barely moves the alignment when a side
/// moves a few per cent; the card's edge against what lies behind it does. Under a bar,
/// blur and a colour cast the random set's scenes 229 and 318 (the rocket card) ended
/// 5.4 % and 6.6 % off in size on the alignment alone, 0.7 % and 1.5 % with the outline.
fn outlined(two: &TwoEyes, shown: &PoseSize, q: &PoseSize, box_px: [f64; 2]) -> f64 {
    alignment(two, shown, q, box_px) + OUTLINE_WEIGHT * outline::contrast(two, q, box_px)
}

/// The weight of the outline in [`outlined`] (the one measured on the random set): one
/// side of four moved from where the brightness barely steps onto a card's edge that
/// steps by 0.3 of the full range gains about 0.04.
const OUTLINE_WEIGHT: f64 = 0.5;

/// The growth of `q`'s side (`length`, `side` as [`PoseSize::resized`]) that lines the
/// photo up best with `shown`'s part of the image, refined to 1 %, and that alignment.
fn best_growth(two: &TwoEyes, shown: &PoseSize, q: &PoseSize, box_px: [f64; 2], length: bool, side: f64) -> (f64, f64) {
    let at = |f: f64| alignment(two, shown, &q.resized(box_px, length, f, side), box_px);
    let coarse = GROWTH.iter().map(|&f| (f, at(f))).max_by(|x, y| x.1.total_cmp(&y.1));
    let (f0, a0) = coarse.expect("growth factors");
    (-5..=5)
        .filter(|&i| i != 0)
        .map(|i| f0 * (1.0 + 0.01 * i as f64))
        .map(|f| (f, at(f)))
        .chain(std::iter::once((f0, a0)))
        .max_by(|x, y| x.1.total_cmp(&y.1))
        .expect("refinement")
}

/// The share of `shown`'s sides left out of [`alignment`]: its edges mix in what lies
/// beyond them.
const MARGIN: f64 = 0.05;

/// The correlation of the photo's brightness with the left eye's brightness at the
/// inner points of `q` that lie on `shown`'s card (inside its rectangle on the plane
/// the two share).
fn alignment(two: &TwoEyes, shown: &PoseSize, q: &PoseSize, box_px: [f64; 2]) -> f64 {
    let [l, b] = shown.size_mm(box_px[0], box_px[1]);
    let s = shown.rotation().inverse() * (q.position - shown.position);
    let (alpha, beta) = (q.alpha, q.beta());
    let (hl, hb) = (0.5 * l * (1.0 - MARGIN), 0.5 * b * (1.0 - MARGIN));
    let on_shown = |x: f32, y: f32| (x as f64 / alpha + s.x).abs() <= hl && (y as f64 / beta + s.y).abs() <= hb;
    let p = two.points;
    let mut subset = PointSet::default();
    for ((&x, &y), &v) in p.inner_x.iter().zip(&p.inner_y).zip(&p.inner_v) {
        if on_shown(x, y) {
            subset.inner_x.push(x);
            subset.inner_y.push(y);
            subset.inner_v.push(v);
        }
    }
    let mut ncc = Ncc::default();
    both_eyes(
        &subset,
        two.rig,
        two.eyes,
        two.left_from_hand,
        q,
        |_, m, (a, _, _), _| ncc.add(m as f32, a),
    );
    ncc.value()
}
