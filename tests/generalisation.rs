//! Scenes nobody tuned for: 40 random scenes, each a card of one test photo in front of
//! a *different* real photograph as the background wall (no collage), anywhere in the
//! field of view inside the default search space, tilted up to 45°, HD and FHD (small
//! cards), one random hand-eye transform each, estimated with the default
//! configuration. About a third are noisy the way a bad frame is: pixel noise, blur
//! (defocus or motion), a colour cast and brightness change, and a bar in front of
//! 15–25 % of the card. The table and the figures print with `--nocapture`.
//!
//! Beside the accuracy suite's hand-made scenes, these are drawn at random: a second
//! check of the verdict on poses nobody chose. Asserted: no pose more than 20 mm or 10°
//! off is reported found, and the share within 10 mm, 5 % and 5° stays at or above its
//! floor (a guard against regressions; whether the targets are reached is printed).
//! `GEN_DRAW=k` draws the k-th 40 scenes (`GEN_DRAW=2`: 40–79) the same way: a fresh
//! check for a change tuned on the first draw (the floor is asserted on the first only).

use std::path::Path;

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use photopose::camera::calibration::Resolution;
use photopose::config::Config;
use photopose::estimator::model::PhotoModel;
use photopose::estimator::oneshot;
use photopose::estimator::pose::{rotation_error_deg, PoseSize};
use photopose::estimator::verify::plane;
use photopose::render::{self, Background, Card, Scene};
use photopose::vision::frame::StereoImages;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use crate::common::data;
use crate::scenes::photo;
use crate::suite::edit;

/// The photos and their boxes (as `photopose model --box`).
const CARDS: [(&str, [i64; 4]); 4] = [
    ("coffee.jpg", [149, 22, 279, 289]),
    ("chelsea.jpg", [70, 20, 280, 270]),
    ("astronaut.jpg", [120, 20, 270, 330]),
    ("rocket.jpg", [150, 60, 340, 300]),
];

/// Share of scenes within 10 mm, 5 % and 5° measured on 2026-12-03: 39 of 40 (27 of
/// 27 clean, 12 of 13 noisy: 92.3 %; over eight draws the noisy share is 75.7 %, the
/// target is not reached); the floor is 2 scenes below (a guard against regressions,
/// not the target).
const SUCCESS_FLOOR: f64 = 0.925;

/// One random scene's parameters and its rendering.
struct Drawn {
    name: String,
    fhd: bool,
    noise: f64,
    /// What else degrades a noisy scene (blur, colour, the bar), for the table.
    degraded: String,
    tilt_deg: f64,
    extent_px: f64,
    size_mm: [f64; 2],
    hand_from_model: Isometry3<f64>,
    config: Config,
    model: PhotoModel,
    images: StereoImages,
}

impl Drawn {
    /// The card's true pose and size.
    fn truth(&self) -> PoseSize {
        PoseSize::from_pose(&self.hand_from_model, self.size_mm, self.model.l_p, self.model.b_p)
    }

    /// The one-shot estimate with the scene's configuration and seed.
    fn estimated(&self) -> photopose::estimator::ga::Outcome {
        let (generations, seed) = (self.config.ga.generations, self.config.ga.seed);
        oneshot::run(&self.model, &self.images, &self.config, generations, seed, &mut |_| {}).expect("calibrated")
    }

    /// The frame prepared for the search with the scene's configuration.
    fn prepared(&self) -> oneshot::Prepared {
        oneshot::Prepared::new(&self.model, &self.images, &self.config).expect("calibrated")
    }
}

/// A card position along a random line of sight at depth `z`, inside the default
/// search space (hand frame = left camera frame here before the hand-eye transform).
fn position(rng: &mut StdRng, rig: &photopose::camera::StereoRig, z: f64) -> Vector3<f64> {
    loop {
        let u = rng.random_range(0.1..0.9) * rig.width as f64;
        let v = rng.random_range(0.1..0.9) * rig.height as f64;
        let p = rig.left.ray(u, v) * z;
        if p.x.abs() < 260.0 && p.y.abs() < 260.0 {
            return p;
        }
    }
}

/// Scene `i`: card, background photo, resolution, pose, noise and hand-eye drawn from
/// a generator seeded with `i`; a noisy one also blurred, recoloured and partly hidden
/// ([`Degradation`]).
fn draw(i: u64) -> Drawn {
    draw_degraded(i, true)
}

/// Scene `i` as [`draw`] draws it; `degraded` false leaves a noisy scene with its pixel
/// noise only.
fn draw_degraded(i: u64, degraded: bool) -> Drawn {
    let mut rng = StdRng::seed_from_u64(7000 + i);
    let card = rng.random_range(0..CARDS.len());
    let wall = (card + rng.random_range(1..CARDS.len())) % CARDS.len();
    let (name, bbox) = CARDS[card];
    let fhd = rng.random_bool(0.3);
    let mut config = Config::load(None).unwrap();
    let offset = Vector3::new(rng.random_range(-40.0..40.0), rng.random_range(-40.0..40.0), 0.0);
    config.left_from_hand = Isometry3::from_parts(
        Translation3::from(offset),
        UnitQuaternion::from_scaled_axis(Vector3::z() * rng.random_range(-0.2..0.2)),
    );
    let rig = config
        .calibration
        .rig(if fhd { Resolution::FHD } else { Resolution::HD })
        .unwrap();
    let z = rng.random_range(450.0..1000.0);
    let length = if fhd {
        rng.random_range(55.0..90.0)
    } else {
        rng.random_range(70.0..220.0)
    };
    let aspect = bbox[3] as f64 / bbox[2] as f64 * rng.random_range(0.85..1.15);
    let tilt = rng.random_range(0.0..45f64).to_radians();
    let axis = rng.random_range(0.0..std::f64::consts::TAU);
    let rotation = UnitQuaternion::from_scaled_axis(Vector3::new(axis.cos(), axis.sin(), 0.0) * tilt)
        * UnitQuaternion::from_scaled_axis(Vector3::z() * rng.random_range(-0.6..0.6));
    let left_from_model = Isometry3::from_parts(Translation3::from(position(&mut rng, &rig, z)), rotation);
    let hand_from_model = config.left_from_hand.inverse() * left_from_model;
    let noise = if rng.random_bool(0.35) {
        rng.random_range(3.0..9.0)
    } else {
        0.0
    };
    let full = photo(name);
    let [x, y, w, h] = bbox;
    let size_mm = [length, length * aspect];
    let mut scene = Scene {
        card: Card {
            texture: image::imageops::crop_imm(&full, x as u32, y as u32, w as u32, h as u32).to_image(),
            hand_from_model,
            size_mm,
        },
        background: Background::from_texture(
            &photo(CARDS[wall].0),
            rng.random_range(1500.0..2500.0),
            rng.random_range(2.5..5.0),
        ),
        noise_sigma: noise,
        brightness: 1.0,
        occluder: None,
        seed: i,
    };
    let degradation = (degraded && noise > 0.0).then(|| Degradation::draw(i));
    if let Some(d) = &degradation {
        scene.occluder = d.occluder(&(config.left_from_hand * hand_from_model), size_mm, i);
    }
    let sbs = render::render(&rig, &config.left_from_hand, &scene);
    let mut images = StereoImages::from_sbs(&sbs, Path::new("scene")).unwrap();
    if let Some(d) = &degradation {
        d.apply(&mut images);
    }
    let model = PhotoModel::build(
        &full,
        &data(format!("photos/{name}")),
        bbox,
        &config.model,
        &config.fitness.classes(),
    )
    .unwrap();
    Drawn {
        name: format!("{i:>2} {name} on {}", CARDS[wall].0),
        fhd,
        noise,
        degraded: degradation.as_ref().map_or(String::new(), Degradation::label),
        tilt_deg: tilt.to_degrees(),
        extent_px: length / z * rig.left.fx,
        size_mm,
        hand_from_model,
        config,
        model,
        images,
    }
}

/// What degrades a noisy scene beyond its pixel noise, drawn from its own generator
/// (the clean scenes and every scene's pose stay as they were drawn before).
struct Degradation {
    /// Gaussian blur sigma (defocus), or a motion stroke's length and direction, px.
    blur: Blur,
    /// Per-channel gains on the whole frame: a colour cast times a brightness change.
    gains: [f64; 3],
    /// The share of the card a bar in front of it covers, and the bar's colour.
    bar: (f64, [u8; 3]),
}

enum Blur {
    Defocus(f32),
    Motion(f64, [f64; 2]),
}

/// Bar colours: grey, the target photos' reds, browns and blues, skin, green.
const BARS: [[u8; 3]; 6] = [
    [128, 128, 128],
    [200, 40, 30],
    [150, 90, 50],
    [40, 80, 200],
    [225, 170, 140],
    [60, 140, 60],
];

impl Degradation {
    fn draw(i: u64) -> Self {
        let mut rng = StdRng::seed_from_u64(9000 + i);
        let blur = if rng.random_bool(0.5) {
            Blur::Defocus(rng.random_range(0.6..1.5))
        } else {
            let a = rng.random_range(0.0..std::f64::consts::PI);
            Blur::Motion(rng.random_range(1.0..3.0), [a.cos(), a.sin()])
        };
        let light = rng.random_range(0.7..1.3);
        let gains = [0, 1, 2].map(|_| light * rng.random_range(0.88..1.12));
        let fraction = rng.random_range(0.15..0.25);
        let colour = BARS[rng.random_range(0..BARS.len())];
        Self {
            blur,
            gains,
            bar: (fraction, colour),
        }
    }

    /// The bar in front of the card posed `left_from_model` (`size_mm`; `seed` picks its side).
    fn occluder(&self, left_from_model: &Isometry3<f64>, size_mm: [f64; 2], seed: u64) -> Option<render::Occluder> {
        let (fraction, colour) = self.bar;
        render::Occluder::covering(
            left_from_model,
            size_mm,
            fraction,
            render::OccluderFill::Solid(colour),
            seed,
        )
    }

    /// What the table prints.
    fn label(&self) -> String {
        let blur = match self.blur {
            Blur::Defocus(s) => format!("defocus {s:.1}"),
            Blur::Motion(l, _) => format!("motion {l:.1}"),
        };
        let [r, g, b] = self.gains;
        let (fraction, colour) = self.bar;
        format!(
            "{blur}, gains {r:.2}/{g:.2}/{b:.2}, bar {:.0} % {colour:?}",
            fraction * 100.0
        )
    }

    /// The frame edits (after rendering): blur, then the colour.
    fn apply(&self, images: &mut StereoImages) {
        match self.blur {
            Blur::Defocus(sigma) => edit::defocus(images, sigma),
            Blur::Motion(length, dir) => edit::motion(images, length, dir),
        }
        edit::white_balance(images, self.gains);
    }
}

/// The scenes drawn: 0–39, or `GEN_DRAW=k` for the k-th draw of 40 (`GEN_DRAW=2` is
/// scenes 40–79: a fresh set for a change tuned on the first).
fn drawn() -> std::ops::Range<u64> {
    let k: u64 = std::env::var("GEN_DRAW")
        .ok()
        .and_then(|k| k.parse().ok())
        .unwrap_or(1)
        .max(1);
    (k - 1) * 40..k * 40
}

/// Whether scene `i` runs: all, or those listed in `GEN_SCENES` (`GEN_SCENES=8,11`;
/// then the floor is not asserted).
fn chosen(i: u64) -> bool {
    std::env::var("GEN_SCENES").map_or(true, |l| l.split(',').any(|s| s.trim() == i.to_string()))
}

/// Whether an estimate's [`errors`] lie within 10 mm, 5 % and 5°.
fn within_bounds([pos, size, rot]: [f64; 3]) -> bool {
    pos <= 10.0 && size <= 0.05 && rot <= 5.0
}

/// Errors of an estimate: position mm, worst relative size, rotation degrees.
fn errors(d: &Drawn, best: &PoseSize) -> [f64; 3] {
    let size = best.size_mm(d.model.l_p, d.model.b_p);
    let rel = |i: usize| (size[i] - d.size_mm[i]).abs() / d.size_mm[i];
    [
        (best.position - d.hand_from_model.translation.vector).norm(),
        rel(0).max(rel(1)),
        rotation_error_deg(&best.rotation(), &d.hand_from_model.rotation),
    ]
}

#[test]
#[ignore = "about three minutes of estimates; CI runs it (see .ci/run)"]
fn generalisation_scenes_are_estimated_or_flagged() {
    let start = std::time::Instant::now();
    println!(
        "\n{:<32} {:>3} {:>5} {:>5} {:>5} | {:>7} {:>6} {:>6} | {:>5} {:>5} {:>5} found | score truth",
        "scene", "res", "noise", "tilt°", "px", "pos mm", "size%", "rot°", "conf", "stereo", "struct"
    );
    let (mut false_found, mut found, mut wrong, mut outranks) = (Vec::new(), 0, 0, 0);
    // Scenes within the bounds, and scenes, clean and noisy.
    let mut by_noise = [[0usize; 2]; 2];
    let n = drawn().filter(|&i| chosen(i)).count();
    for i in drawn().filter(|&i| chosen(i)) {
        let d = draw(i);
        let out = d.estimated();
        let [pos, size, rot] = errors(&d, &out.best);
        let truth = d.truth();
        let score = |p: &PoseSize| oneshot::score_at(&d.model, &d.images, &d.config, p).unwrap().score;
        let (at_result, at_truth) = (score(&out.best), score(&truth));
        outranks += (at_truth > at_result) as usize;
        let v = &out.verdict;
        let good = within_bounds([pos, size, rot]);
        let far = pos > 20.0 || rot > 10.0;
        let set = &mut by_noise[(d.noise > 0.0) as usize];
        set[0] += good as usize;
        set[1] += 1;
        found += v.found as usize;
        wrong += far as usize;
        if far && v.found {
            false_found.push(d.name.clone());
        }
        println!(
            "{:<32} {:>3} {:>5.1} {:>5.1} {:>5.0} | {pos:>7.1} {:>6.1} {rot:>6.1} | {:>5.2} {:>5.2} {:>5.2} {:<5} | {at_result:>5.2} {at_truth:>5.2} {}",
            d.name,
            if d.fhd { "FHD" } else { "HD" },
            d.noise,
            d.tilt_deg,
            d.extent_px,
            size * 100.0,
            v.confidence,
            v.texture.stereo,
            v.texture.structure,
            if v.found { "yes" } else { "no" },
            d.degraded
        );
    }
    let ok = by_noise[0][0] + by_noise[1][0];
    let share = ok as f64 / n as f64;
    let [clean, noisy] = by_noise.map(|[k, m]| k as f64 / m.max(1) as f64);
    let reached = if clean >= 0.95 && noisy >= 0.85 {
        "reached"
    } else {
        "not reached"
    };
    println!(
        "within 10 mm, 5 %, 5°: {ok} of {n} ({:.1} %); clean {} of {} ({:.1} %), noisy {} of {} ({:.1} %): \
         target 95 % clean, 85 % noisy {reached}; reported found: {found}; more than 20 mm or 10° off: {wrong}, of them reported found: {}; \
         the truth outranks the result on {outranks}; {:.0} s",
        share * 100.0,
        by_noise[0][0],
        by_noise[0][1],
        clean * 100.0,
        by_noise[1][0],
        by_noise[1][1],
        noisy * 100.0,
        false_found.len(),
        start.elapsed().as_secs_f64()
    );
    assert!(false_found.is_empty(), "wrong poses reported found: {false_found:?}");
    assert!(
        share >= SUCCESS_FLOOR || n < 40 || drawn().start > 0,
        "{ok} of {n} within 10 mm, 5 %, 5°: below the floor of {:.0} %",
        SUCCESS_FLOOR * 100.0
    );
}

/// The later retries' scan also tries tilted placements (`Problem::scan_tilt`): a cup
/// card tilted 36° and 135 px across (random scene 38), which the facing scan on the
/// half resolution misses (none of its regions within 40 mm of the truth), is its best
/// region then.
#[test]
fn the_tilted_scan_sees_a_card_the_facing_scan_misses() {
    use photopose::estimator::oneshot::Prepared;
    let d = draw(38);
    let mut config = d.config.clone();
    // The finer retries' levels: the scan runs on the half resolution.
    config.robust.pyramid_levels = 2;
    let prepared = Prepared::new(&d.model, &d.images, &config).expect("calibrated");
    let distances = |tilt_deg: f64| -> Vec<f64> {
        let mut problem = prepared.problem(&config);
        problem.scan_tilt = tilt_deg.to_radians();
        scan_region_distances(&problem, &d)
    };
    let facing = distances(0.0);
    let nearest = facing.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(nearest > 40.0, "a facing region came {nearest:.0} mm near");
    let tilted = distances(35.0);
    assert!(tilted[0] < 20.0, "the best tilted region is {:.0} mm off", tilted[0]);
}

/// The last retry's scan, dense and one level finer over small apparent sizes only
/// (`Problem::scan_small_only`): a cat card 83 px across, tilted 30°, on the astronaut
/// photo (random scene 200), which the dense scan on the quarter resolution misses
/// (none of its regions within 40 mm of the truth; the nearest 62 mm off), is its best
/// region (6 mm off).
#[test]
fn the_fine_dense_scan_sees_a_small_card_the_coarse_one_misses() {
    use photopose::estimator::oneshot::Prepared;
    let d = draw(200);
    let distances = |levels: usize| -> Vec<f64> {
        let mut config = d.config.clone();
        config.robust.pyramid_levels = levels;
        let prepared = Prepared::new(&d.model, &d.images, &config).expect("calibrated");
        let mut problem = prepared.problem(&config);
        problem.scan_dense = true;
        problem.scan_small_only = levels < d.config.robust.pyramid_levels;
        scan_region_distances(&problem, &d)
    };
    let coarse = distances(d.config.robust.pyramid_levels);
    let nearest = coarse.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(nearest > 40.0, "a coarse region came {nearest:.0} mm near");
    let fine = distances(d.config.robust.pyramid_levels - 1);
    assert!(fine[0] < 20.0, "the best fine region is {:.0} mm off", fine[0]);
}

/// How far (mm) from scene `d`'s truth lies each region the acquisition scan of
/// `problem` keeps, best first.
fn scan_region_distances(problem: &photopose::estimator::ga::Problem, d: &Drawn) -> Vec<f64> {
    let truth = d.hand_from_model.translation.vector;
    photopose::estimator::ga::scan::seeds(problem, 40)
        .regions
        .iter()
        .map(|g| (problem.bounds.decode(g).position - truth).norm())
        .collect()
}

/// The left image's ridge at a steep tilt: the truth's plane turned 3° about the
/// camera's x or y axis, the card's corners where the left eye's rays through the true
/// ones meet it (they move 2–4 px in the image on a 90–140 px card: the colour fitness
/// barely sees it), 2–8 % off in size and 3–4° in rotation. The sweep of the plane
/// between the two eyes brings tilt and size back from every side (scene 23 with its
/// pixel noise only; a partly hidden card is the next test's).
#[test]
fn the_plane_of_a_steeply_tilted_card_is_settled_by_the_two_eyes() {
    for i in [11, 23] {
        for (what, [before, after]) in turned_and_settled(&draw_degraded(i, false)) {
            assert!(before[2] > 2.5, "{what}");
            assert!(after[0] < 1.0 && after[1] < 0.015 && after[2] < 1.0, "{what}");
        }
    }
}

/// The same with a bar in front of a fifth of the card, blur and a colour cast (random
/// scenes 1 and 30: 198 px tilted 40°, 156 px tilted 7°), to within 2 mm, 2 % and 2°.
/// The bar shows each eye a different surface at any plane; the sweep also leaves
/// those points out ([`plane::TwoEyes::trimmed_agreement`]) instead of only following
/// the bar's depth (scene 30 then ends 7° off). Not every such card settles: scene 16
/// (98 px tilted 10°) turned 3° about x ends 3.4° off, a limit the docs state.
#[test]
fn the_plane_of_a_partly_hidden_card_is_settled_by_the_two_eyes() {
    for i in [1, 30] {
        for (what, [before, after]) in turned_and_settled(&draw(i)) {
            assert!(before[2] > 2.0, "{what}");
            assert!(after[0] < 2.0 && after[1] < 0.02 && after[2] < 2.0, "{what}");
        }
    }
}

/// Scene `d`'s truth turned 3° either way about the left camera's x and y axes, its
/// left image held ([`plane::replaced`]), and settled ([`plane::settle`]): a description
/// and the errors before and after.
fn turned_and_settled(d: &Drawn) -> Vec<(String, [[f64; 3]; 2])> {
    let prepared = d.prepared();
    let (two, box_px) = (prepared.two_eyes(), prepared.scorer.box_px);
    let left_from_hand = &d.config.left_from_hand;
    let truth = d.truth();
    let tilt = 3f64.to_radians();
    [[tilt, 0.0], [-tilt, 0.0], [0.0, tilt], [0.0, -tilt]]
        .into_iter()
        .map(|off| {
            let moved = plane::replaced(&truth, left_from_hand, box_px, 1.0, off);
            let settled = plane::settle(&two, &moved, box_px);
            let errors = [moved, settled].map(|p| errors(d, &p));
            let what = format!(
                "{}, turned {off:.3?}: {:.3?} -> {:.3?} (mm, size, °)",
                d.name, errors[0], errors[1]
            );
            (what, errors)
        })
        .collect()
}

/// A model shrunk onto part of its card lines the photo up with the image only once it
/// is grown back ([`hidden::uncovered`]). The truth of two degraded scenes (a bar over
/// 16–24 % of the card, blur, a colour cast) cut by a quarter on the side the bar hides
/// grows back to within 2 mm and 2 %. Cut on another side, with the bar still inside
/// the model, the smooth rocket photo of scene 8 grows into the wall (140–200 mm off):
/// the verdict must not call any such pose found. A truth cut by 30 % about its centre
/// grows back too (scene 43). The truth of two clean scenes stays within 1 mm, 1 % and
/// 0.5° of itself.
#[test]
fn a_model_shrunk_onto_part_of_its_card_is_grown_back() {
    use photopose::estimator::verify::hidden;
    let prepared_truth = |i: u64| {
        let d = draw(i);
        let (prepared, truth) = (d.prepared(), d.truth());
        (d, prepared, truth)
    };
    for i in [8, 23] {
        let (d, prepared, truth) = prepared_truth(i);
        let box_px = prepared.scorer.box_px;
        for (length, side) in [(false, -0.5), (true, -0.5), (true, 0.5), (false, 0.5)] {
            let cut = truth.resized(box_px, length, 0.75, side);
            let grown = hidden::uncovered(&prepared.two_eyes(), &cut, box_px);
            let [before, after] = [cut, grown].map(|p| errors(&d, &p));
            let what = format!("scene {i}, side {length} {side}: {before:.3?} -> {after:.3?} (mm, size, °)");
            if !length && side < 0.0 {
                assert!(after[0] < 2.0 && after[1] < 0.02, "the bar's side, {what}");
            }
            let far = after[0] > 20.0 || after[2] > 10.0;
            assert!(!(far && prepared.verdict(&grown).found), "found: {what}");
        }
    }
    // A smooth photo under a bar (the rocket, sky on both sides): the search shrank the
    // model about its centre, 33 % short (scene 43 of the second draw). Scene 64's cut
    // grows 166 mm off along one side: not found.
    for i in [43, 64] {
        let (d, prepared, truth) = prepared_truth(i);
        let box_px = prepared.scorer.box_px;
        let cut = truth.resized(box_px, true, 0.7, 0.0);
        let grown = hidden::uncovered(&prepared.two_eyes(), &cut, box_px);
        let [before, after] = [cut, grown].map(|p| errors(&d, &p));
        let what = format!("scene {i}, about the centre: {before:.3?} -> {after:.3?} (mm, size, °)");
        assert!(i != 43 || (after[0] < 2.0 && after[1] < 0.02), "{what}");
        let far = after[0] > 20.0 || after[2] > 10.0;
        assert!(!(far && prepared.verdict(&grown).found), "found: {what}");
    }
    for i in [5, 24] {
        let (d, prepared, truth) = prepared_truth(i);
        let kept = errors(
            &d,
            &hidden::uncovered(&prepared.two_eyes(), &truth, prepared.scorer.box_px),
        );
        println!("scene {i}, the truth: {kept:.3?}");
        assert!(
            kept[0] < 1.0 && kept[1] < 0.01 && kept[2] < 0.5,
            "scene {i}, the truth: {kept:.3?}"
        );
    }
}

/// The search may shrink a model onto the visible part of a card and turn it a few
/// degrees as well: on noisy scene 292 of the eighth draw (a cat card tilted 37° and
/// 116 px across at FHD, a blue bar over 22 % of it, defocus) the model kept 86 % of
/// the length and 53 % of the width, 10.7° off in rotation (mostly its roll), and its
/// sides grown at that roll ended 19 % off in size. The truth cut by a quarter on the
/// bar's side and turned 4° or 8° either way grows and turns back to within 2 mm, 2 %
/// and 1°.
#[test]
fn a_shrunk_and_turned_model_is_grown_and_turned_back() {
    use photopose::estimator::verify::hidden;
    let d = draw(292);
    let (prepared, truth) = (d.prepared(), d.truth());
    let box_px = prepared.scorer.box_px;
    for roll in [-8.0f64, -4.0, 4.0, 8.0] {
        let cut = truth
            .resized(box_px, false, 0.75, -0.5)
            .turned(Vector3::z(), roll.to_radians());
        let grown = hidden::uncovered(&prepared.two_eyes(), &cut, box_px);
        let [before, after] = [cut, grown].map(|p| errors(&d, &p));
        let what = format!("turned {roll}°: {before:.3?} -> {after:.3?} (mm, size, °)");
        assert!(after[0] < 2.0 && after[1] < 0.02 && after[2] < 1.0, "{what}");
    }
}

/// Under blur, a colour cast and a bar, the search can end a few per cent long or short
/// along one axis, about the card's centre, where no side's growth lines the photo up
/// clearly better: scene 224 of the sixth draw (a coffee card, defocused, under a bar)
/// ended 7.1 % short, scene 313 of the eighth 6.3 %. A result has its edges and roll
/// lined up even where no side grows ([`hidden::uncovered`]): the truth of each, cut
/// or stretched by 7 % along either axis, comes back within 3 %; the truth stays within
/// 3 %.
#[test]
fn a_model_a_few_per_cent_off_in_size_is_realigned() {
    use photopose::estimator::verify::hidden;
    for i in [224, 313] {
        let d = draw(i);
        let (prepared, truth) = (d.prepared(), d.truth());
        let box_px = prepared.scorer.box_px;
        let kept = errors(&d, &hidden::uncovered(&prepared.two_eyes(), &truth, box_px));
        assert!(
            kept[0] < 2.0 && kept[1] < 0.03 && kept[2] < 1.0,
            "scene {i}, the truth: {kept:.3?}"
        );
        for (length, factor) in [(true, 0.93), (false, 0.93), (true, 1.07), (false, 1.07)] {
            let off = truth.resized(box_px, length, factor, 0.0);
            let back = hidden::uncovered(&prepared.two_eyes(), &off, box_px);
            let [before, after] = [off, back].map(|p| errors(&d, &p));
            let what = format!("scene {i}, length {length} ×{factor}: {before:.3?} -> {after:.3?} (mm, size, °)");
            assert!(after[0] < 2.0 && after[1] < 0.03 && after[2] < 1.5, "{what}");
            println!("{what}");
        }
    }
}

/// The rocket card on its smooth sky, under a bar, blurred and recoloured (scenes 229 and
/// 318 of the random set's sixth and eighth draws): the photo's texture barely tells
/// where its sides are, and the search's result ended 5.4 % and 6.6 % off in size when
/// the uncovering's climbs read that texture alone. With the card's outline (the
/// brightness step across its sides) they end within 10 mm, 5 % and 5°.
#[test]
fn the_outline_sizes_a_card_whose_photo_is_smooth_near_its_border() {
    for i in [229, 318] {
        assert_estimated_within_bounds(i);
    }
}

/// A search under a bar can end short or long along one axis about the card's centre,
/// both its sides a few millimetres off: scene 48 of the second draw (a cat card
/// 180 × 175 mm, defocused and darkened, a red bar over a quarter of it) ended 5.3 %
/// short in breadth, its two sides 5.5 and 3.8 mm in, when the uncovering's edge climb
/// moved one side at a time. It also stretches each axis about its centre, and the
/// estimate lands within 10 mm, 5 % and 5°.
#[test]
fn an_axis_short_about_its_centre_is_stretched_back() {
    assert_estimated_within_bounds(48);
}

/// A search under a bar can find the visible part of a card at a wrong tilt, and the
/// uncovering grows it back at that tilt: scenes 236 and 238 of the sixth draw (the
/// rocket card, blurred and recoloured, a green bar over 16–17 %) ended 38.9° and 11.2°
/// off in rotation, 32.8 % and 15.1 % in size, with the same image as the truth (tilted
/// and stretched along the tilt) and scoring below it. Turned to another plane with the
/// same image, where the score and both eyes agree, they end within 10 mm, 5 % and 5°.
#[test]
fn a_card_grown_back_at_a_wrong_tilt_is_turned_to_its_plane() {
    for i in [236, 238] {
        assert_estimated_within_bounds(i);
    }
}

/// Where five searches find nothing, the sixth (a dense scan one level finer) counts
/// only where it is found or scores clearly higher: on scene 434 of the eleventh draw
/// (the coffee card, blurred, darkened to 0.7 and a bar over 19 %) it found the card
/// 1.5 mm off, scoring 6.26 against 4.97 for the best of the five (215 mm off), but
/// the verdict does not find it (the bar). Kept, it ends within 10 mm, 5 % and 5°.
#[test]
fn a_sixth_search_that_scores_clearly_higher_is_kept_though_not_found() {
    assert_estimated_within_bounds(434);
}

/// The climbs of a result's edges stop on the first peak they meet, and a found result
/// was not lined up at all: on scene 64 of the second draw (the rocket card under a bar
/// over 22 %, motion blur) the side the bar hid grew back only part of the way (14.9 %
/// short, 21° off, not found); scene 347 of the ninth (the same card, a bar over 18 %,
/// defocus, darkened to 0.7) was found 22 % short. Each side's and axis's extent scanned
/// over 0.9–1.5 before the climbs, and every result lined up, both end within 10 mm, 5 %
/// and 5°.
#[test]
fn a_side_left_short_is_scanned_back_found_or_not() {
    for i in [64, 347] {
        assert_estimated_within_bounds(i);
    }
}

/// Estimates scene `i` with its configuration and asserts the result lies within 10 mm,
/// 5 % and 5° of the truth.
fn assert_estimated_within_bounds(i: u64) {
    let d = draw(i);
    let errors = errors(&d, &d.estimated().best);
    let [pos, size, rot] = errors;
    let what = format!("scene {i}: {pos:.1} mm, {:.1} %, {rot:.1}°", size * 100.0);
    println!("{what}");
    assert!(within_bounds(errors), "{what}");
}

/// A search can end on a local peak of the full resolution that the half resolution's
/// wider peak leads out of: on clean scene 109 of the third draw (a cat card tilted 40°
/// on a dark helmet) it returned a model 14.6 mm off, 42 % short and turned 24°, scoring
/// 3.8 against the truth's 8.2. Such poses (the truth cut to 58 % of its length, turned
/// 24° about each of 8 axes in its plane, moved 13 mm), polished again from the half
/// resolution, reach the card and are found; the truth itself stays where it is.
#[test]
fn a_result_on_a_local_peak_is_polished_again() {
    let d = draw(109);
    let prepared = d.prepared();
    let problem = prepared.problem(&d.config);
    let truth = d.truth();
    let outcome = |best: PoseSize| photopose::estimator::ga::Outcome {
        best,
        fitness: problem.evaluate(0, &problem.bounds.encode(&best)),
        generations: 0,
        searches: 1,
        evaluations: 0,
        snapshots: Vec::new(),
        verdict: prepared.verdict(&best),
    };
    for a in 0..8 {
        let angle = std::f64::consts::TAU * a as f64 / 8.0;
        let axis = Vector3::new(angle.cos(), angle.sin(), 0.0);
        let mut off = truth
            .resized(prepared.scorer.box_px, true, 0.58, 0.0)
            .turned(axis, 24f64.to_radians());
        off.position += truth.rotation() * Vector3::new(8.0, -10.0, 0.0);
        let mut polished = outcome(off);
        assert!(!polished.verdict.found, "axis {a}: the start is found");
        prepared.repolish(&problem, &mut polished, 1);
        let [before, after] = [off, polished.best].map(|p| errors(&d, &p));
        let what = format!("axis {a}: {before:.3?} -> {after:.3?} (mm, size, °)");
        assert!(after[0] < 2.0 && after[1] < 0.05 && after[2] < 3.0, "{what}");
        assert!(polished.verdict.found, "not found: {what}");
    }
    let mut kept = outcome(truth);
    prepared.repolish(&problem, &mut kept, 1);
    let moved = errors(&d, &kept.best);
    assert!(
        moved[0] < 1.0 && moved[1] < 0.02 && moved[2] < 2.0,
        "the truth moved: {moved:.3?}"
    );
}
