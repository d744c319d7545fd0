//! The accuracy suite: every rendered scene estimated in the robust (default) and the
//! paper mode; the robust mode must reach the error bounds, the paper mode must
//! do better than chance, and both must return poses the search space allows.

use photopose::config::Config;
use photopose::estimator::ga::Outcome;
use photopose::estimator::oneshot;
use photopose::estimator::pose::rotation_error_deg;
use photopose::estimator::settings::Mode;

use crate::scenes::{self, Rendered};

/// Position (mm), size (relative, worst of L and B) and rotation (degrees) errors.
#[derive(Debug, Clone, Copy)]
pub struct Errors {
    /// Distance of the positions, mm.
    pub position: f64,
    /// Worst relative error of L and B.
    pub size: f64,
    /// Angle between the rotations, degrees.
    pub rotation: f64,
}

/// The errors of `outcome`'s best individual against the scene's truth.
pub fn errors(r: &Rendered, outcome: &Outcome) -> Errors {
    let best = &outcome.best;
    let truth_size = r.spec.size_mm;
    let size = best.size_mm(r.model.l_p, r.model.b_p);
    Errors {
        position: (best.position - r.hand_from_model.translation.vector).norm(),
        size: ((size[0] - truth_size[0]).abs() / truth_size[0]).max((size[1] - truth_size[1]).abs() / truth_size[1]),
        rotation: rotation_error_deg(&best.rotation(), &r.hand_from_model.rotation),
    }
}

/// The median of `v` (NaN-free); NaN when empty.
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        f64::NAN
    } else if n % 2 == 1 {
        v[n / 2]
    } else {
        (v[n / 2 - 1] + v[n / 2]) / 2.0
    }
}

/// Estimates `r` with the default generations and seed in `mode`; checks the result is
/// sound and returns its errors with the outcome.
pub fn run(r: &Rendered, mode: Mode) -> (Errors, Outcome) {
    let mut config = r.config.clone();
    config.ga.mode = mode;
    let out = oneshot::run(
        &r.model,
        &r.images,
        &config,
        config.ga.generations,
        config.ga.seed,
        &mut |_| {},
    )
    .expect("scene matches the calibration");
    assert_sound(r, &config, &out);
    let e = errors(r, &out);
    assert!(
        e.position.is_finite() && e.size.is_finite() && (0.0..=180.0).contains(&e.rotation),
        "{} {mode:?}: errors {e:?}",
        r.spec.name
    );
    (e, out)
}

/// An estimate of either mode is a pose and size inside the search space, with a finite
/// fitness.
fn assert_sound(r: &Rendered, config: &Config, out: &Outcome) {
    let within = |v: f64, [lo, hi]: [f64; 2]| {
        let slack = 1e-9 * (hi - lo);
        (lo - slack..=hi + slack).contains(&v)
    };
    let (s, best) = (&config.search, &out.best);
    let [length, _] = best.size_mm(r.model.l_p, r.model.b_p);
    let what = format!("{} {:?}: {best:?}, {:?}", r.spec.name, config.ga.mode, out.fitness);
    assert!(within(best.position.x, s.x_mm), "x outside {:?}: {what}", s.x_mm);
    assert!(within(best.position.y, s.y_mm), "y outside {:?}: {what}", s.y_mm);
    assert!(within(best.position.z, s.z_mm), "z outside {:?}: {what}", s.z_mm);
    assert!(within(length, s.size_mm), "length outside {:?}: {what}", s.size_mm);
    assert!(within(best.k, s.aspect_k), "k outside {:?}: {what}", s.aspect_k);
    assert!(
        best.eps.iter().all(|e| (-1.0..=1.0).contains(e)),
        "ε outside [-1, 1]: {what}"
    );
    assert!(out.fitness.f.is_finite() && out.fitness.score.is_finite(), "{what}");
}

/// The accuracy targets on every rendered scene (median ≤ 10 mm, 5 %, 5° clean;
/// ≤ 20 mm, 10 %, 10° noisy/occluded), with a table of both modes
/// (`cargo test -- --nocapture rendered_scenes` shows it). The paper mode, fooled by the
/// clutter, has no targets; it must still beat chance (see the end).
#[test]
fn rendered_scenes_reach_the_accuracy_targets() {
    let specs = scenes::all();
    println!(
        "\n{:<18} {:>5} | {:>8} {:>7} {:>7} | {:>8} {:>7} {:>7}",
        "scene", "hard", "rob pos", "size%", "rot°", "pap pos", "size%", "rot°"
    );
    let mut rows = Vec::new();
    for (i, spec) in specs.iter().enumerate() {
        let rendered = scenes::render(spec, 100 + i as u64);
        let (robust, _) = run(&rendered, Mode::Robust);
        let (paper, _) = run(&rendered, Mode::Paper);
        println!(
            "{:<18} {:>5} | {:>8.1} {:>7.1} {:>7.1} | {:>8.1} {:>7.1} {:>7.1}",
            spec.name,
            spec.hard(),
            robust.position,
            robust.size * 100.0,
            robust.rotation,
            paper.position,
            paper.size * 100.0,
            paper.rotation
        );
        rows.push((spec.hard(), robust, paper));
    }
    for (hard, label, bounds) in [
        (false, "clean", (10.0, 0.05, 5.0)),
        (true, "noisy/occluded", (20.0, 0.10, 10.0)),
    ] {
        let sel: Vec<&Errors> = rows.iter().filter(|r| r.0 == hard).map(|r| &r.1).collect();
        let pos = median(sel.iter().map(|e| e.position).collect());
        let size = median(sel.iter().map(|e| e.size).collect());
        let rot = median(sel.iter().map(|e| e.rotation).collect());
        let paper: Vec<&Errors> = rows.iter().filter(|r| r.0 == hard).map(|r| &r.2).collect();
        println!(
            "median {label:<15} robust: {pos:.1} mm, {:.1} %, {rot:.1}°   paper: {:.1} mm, {:.1} %, {:.1}°",
            size * 100.0,
            median(paper.iter().map(|e| e.position).collect()),
            median(paper.iter().map(|e| e.size).collect()) * 100.0,
            median(paper.iter().map(|e| e.rotation).collect()),
        );
        assert!(
            pos <= bounds.0,
            "{label}: median position error {pos:.1} mm > {} mm",
            bounds.0
        );
        assert!(
            size <= bounds.1,
            "{label}: median size error {:.1} % > {} %",
            size * 100.0,
            bounds.1 * 100.0
        );
        assert!(
            rot <= bounds.2,
            "{label}: median rotation error {rot:.1}° > {}°",
            bounds.2
        );
    }
    // The paper mode against chance. Positions drawn uniformly from the search space
    // (x, y ±300 mm, z 300–1200 mm) have a median error over these 16 cards of about
    // 370 mm (below 308 mm in 5 % of draws) and come within 150 mm of a card on 0.7 of
    // them on average. The paper mode measured a median of 239.7 mm and came within
    // 150 mm on 6 scenes: the bounds leave it a margin and stay below chance.
    let paper: Vec<f64> = rows.iter().map(|r| r.2.position).collect();
    let near = paper.iter().filter(|&&e| e <= 150.0).count();
    let paper_median = median(paper);
    println!(
        "paper mode: median position error {paper_median:.1} mm, within 150 mm on {near} of {} scenes",
        rows.len()
    );
    assert!(
        paper_median <= 300.0,
        "paper mode: median position error {paper_median:.1} mm > 300 mm"
    );
    assert!(
        near >= 3,
        "paper mode: within 150 mm on only {near} of {} scenes",
        rows.len()
    );
}

/// Diagnosis aid (`cargo test --release -- --ignored --nocapture diagnose`): fitness of
/// the ground truth against the found optimum on each scene, plus overlays in `target/`.
#[test]
#[ignore]
fn diagnose() {
    use photopose::estimator::oneshot::Prepared;
    use photopose::estimator::pose::PoseSize;
    let only = std::env::var("SCENE").ok();
    for (i, spec) in scenes::all().iter().enumerate() {
        if only.as_deref().is_some_and(|o| o != spec.name) {
            continue;
        }
        let r = scenes::render(spec, 100 + i as u64);
        let prepared = Prepared::new(&r.model, &r.images, &r.config).unwrap();
        let problem = prepared.problem(&r.config);
        let truth = PoseSize::from_pose(&r.hand_from_model, spec.size_mm, r.model.l_p, r.model.b_p);
        let tg = problem.bounds.encode(&truth);
        {
            use rand::SeedableRng;
            let mut rng = rand::rngs::StdRng::seed_from_u64(5);
            let mut best = 0.0f64;
            let mut nonzero = 0;
            for _ in 0..20000 {
                let g = photopose::estimator::ga::robust::view_sample(&problem, &mut rng);
                let f = problem.evaluate(2, &g).f;
                best = best.max(f);
                nonzero += (f != 0.0) as usize;
            }
            println!("view samples: best L2 {best:.3}, nonzero {nonzero}");
            for d in [0.002, 0.005, 0.01, 0.02, 0.05] {
                let line: Vec<String> = (0..8)
                    .map(|i| {
                        let mut g = tg;
                        g[i] = (g[i] + d).min(1.0);
                        format!("{:.2}", problem.evaluate(2, &g).f)
                    })
                    .collect();
                println!("truth + {d} per gene at L2: {}", line.join(" "));
            }
        }
        let t0 = std::time::Instant::now();
        let out = oneshot::run(&r.model, &r.images, &r.config, 1000, 1, &mut |_| {}).unwrap();
        let dt = t0.elapsed().as_secs_f64();
        let og = problem.bounds.encode(&out.best);
        let levels: Vec<String> = (0..prepared.levels.len())
            .map(|l| {
                format!(
                    "L{l} truth {:.3} found {:.3}",
                    problem.evaluate(l, &tg).f,
                    problem.evaluate(l, &og).f
                )
            })
            .collect();
        let e = errors(&r, &out);
        println!(
            "{:<18} {:.1}s err {:.1}mm {:.1}% {:.1}° | {}",
            spec.name,
            dt,
            e.position,
            e.size * 100.0,
            e.rotation,
            levels.join(" | ")
        );
        let dir = crate::common::repo("target/diagnose");
        std::fs::create_dir_all(&dir).unwrap();
        r.images.to_sbs().save(dir.join(format!("{}.png", spec.name))).unwrap();
        let pic = photopose::cli::report::overlay::draw(
            &r.images,
            &prepared.scorer,
            &prepared.levels[0].rig,
            &r.model,
            &out.best,
        );
        pic.save(dir.join(format!("{}-overlay.png", spec.name))).unwrap();
        let pic = photopose::cli::report::overlay::draw(
            &r.images,
            &prepared.scorer,
            &prepared.levels[0].rig,
            &r.model,
            &truth,
        );
        pic.save(dir.join(format!("{}-truth.png", spec.name))).unwrap();
        let t = problem.evaluate(0, &tg);
        for sn in &out.snapshots {
            println!("gen {} F {:.3} pos {:?}", sn.generation, sn.fitness.f, sn.best.position);
        }
        let pts: Vec<usize> = problem.points.iter().map(|p| p.len()).collect();
        println!(
            "truth F_L {:.3} F_R {:.3}; {} evaluations; points per level {pts:?}",
            t.left, t.right, out.evaluations
        );
    }
}

/// The robust fitness puts its peak at the ground truth: on at least 3 of 4 clean
/// scenes the truth outscores 3000 candidates drawn where the cameras look and every
/// pose 15 mm or 10° away from it (11 of 12 measured).
#[test]
fn ground_truth_is_the_robust_fitness_peak() {
    use photopose::estimator::oneshot::Prepared;
    use photopose::estimator::pose::PoseSize;
    use rand::SeedableRng;
    let mut held = Vec::new();
    let clean: Vec<_> = scenes::all().into_iter().filter(|s| !s.hard()).collect();
    for (i, spec) in clean.iter().enumerate() {
        let r = scenes::render(spec, 100 + i as u64);
        let prepared = Prepared::new(&r.model, &r.images, &r.config).unwrap();
        let problem = prepared.problem(&r.config);
        let truth = PoseSize::from_pose(&r.hand_from_model, spec.size_mm, r.model.l_p, r.model.b_p);
        let f_truth = problem.evaluate(0, &problem.bounds.encode(&truth)).f;
        let mut rng = rand::rngs::StdRng::seed_from_u64(i as u64);
        let mut rival = (0..3000)
            .map(|_| {
                problem
                    .evaluate(0, &photopose::estimator::ga::robust::view_sample(&problem, &mut rng))
                    .f
            })
            .fold(f64::NEG_INFINITY, f64::max);
        for axis in [nalgebra::Vector3::x(), nalgebra::Vector3::y(), nalgebra::Vector3::z()] {
            for sign in [-1.0, 1.0] {
                let shifted = PoseSize {
                    position: truth.position + axis * 15.0 * sign,
                    ..truth
                };
                let turn = nalgebra::UnitQuaternion::from_scaled_axis(axis * (10f64.to_radians() * sign));
                let turned = PoseSize::from_pose(
                    &nalgebra::Isometry3::from_parts(r.hand_from_model.translation, r.hand_from_model.rotation * turn),
                    spec.size_mm,
                    r.model.l_p,
                    r.model.b_p,
                );
                for c in [shifted, turned] {
                    rival = rival.max(problem.evaluate(0, &problem.bounds.encode(&c)).f);
                }
            }
        }
        println!("{:<18} truth F {f_truth:.3}, best rival {rival:.3}", spec.name);
        held.push(f_truth > rival);
    }
    let n = held.iter().filter(|h| **h).count();
    assert!(
        n * 4 >= held.len() * 3,
        "truth is the peak on only {n} of {} clean scenes",
        held.len()
    );
}

/// The one-shot result does not depend on the number of fitness threads: the polish's
/// refinements run side by side, each with its own seeded generator.
#[test]
fn one_shot_is_the_same_on_one_and_two_threads() {
    let spec = &scenes::all()[0];
    let r = scenes::render(spec, 100);
    let on = |threads: usize| {
        let mut config = r.config.clone();
        config.ga.threads = threads;
        oneshot::run(&r.model, &r.images, &config, 300, 7, &mut |_| {}).expect("calibrated")
    };
    let (one, two) = (on(1), on(2));
    assert_eq!(one.best, two.best, "same pose and size on 1 and 2 threads");
    assert_eq!(one.fitness.score, two.fitness.score);
}

/// A search whose verdict finds nothing runs again (`[robust] retries`) from the next
/// seed, one pyramid level finer, and keeps the better-scoring result; a search that
/// finds its object runs once.
#[test]
fn a_search_that_finds_nothing_runs_again_finer() {
    let specs = scenes::all();
    let r = scenes::render(&specs[0], 100);
    let other = specs.iter().find(|s| s.photo != specs[0].photo).expect("another photo");
    let absent = scenes::model(other, &r.config);
    let search = |model: &photopose::estimator::model::PhotoModel, levels: usize, retries: usize, seed: u64| {
        let mut config = r.config.clone();
        config.robust.pyramid_levels = levels;
        config.robust.retries = retries;
        oneshot::run(model, &r.images, &config, 300, seed, &mut |_| {}).expect("calibrated")
    };
    let first = search(&absent, 3, 0, 7);
    assert!(
        !first.verdict.found,
        "the other photo is not in the scene: {:?}",
        first.verdict
    );
    let finer = search(&absent, 2, 0, 8);
    // Both searches, watched: an observer sees their generations one after another.
    let seen = std::sync::Mutex::new(Vec::new());
    let observer = |g: &photopose::estimator::ga::observe::Generation| seen.lock().unwrap().push(g.generation);
    let mut config = r.config.clone();
    config.robust.retries = 1;
    let prepared = oneshot::Prepared::new(&absent, &r.images, &config).expect("calibrated");
    let both = oneshot::search_observed(&prepared, &config, 300, 7, &mut |_| {}, Some(&observer));
    assert_eq!(seen.into_inner().unwrap(), (1..=600).collect::<Vec<_>>());
    assert_eq!(
        (both.searches, both.evaluations),
        (2, first.evaluations + finer.evaluations)
    );
    let kept = if first.fitness.score >= finer.fitness.score {
        &first
    } else {
        &finer
    };
    assert_eq!((both.best, both.fitness.score), (kept.best, kept.fitness.score));

    let once = search(&r.model, 3, 0, 7);
    assert!(once.verdict.found, "{}: {:?}", r.spec.name, once.verdict);
    let found = search(&r.model, 3, 3, 7);
    assert_eq!(
        (found.searches, found.best, found.evaluations),
        (1, once.best, once.evaluations)
    );
}
