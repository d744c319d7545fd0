//! The accuracy suite: rendered scenes nobody tuned the estimator for, to predict how it
//! does on new ones. Real photographs as walls (some with large areas of the card's hue,
//! some with same-hue patches painted beside the card), small cards at FHD and HD, cards
//! anywhere in the view, tilted up to 45°, rolled, stretched, seen through a hand-eye
//! transform, printed differently from the model's photo (category level), and hard
//! scenes with noise, blur, other light, white balance and occluders. Every scene uses
//! the default search space and the example calibration with its lens distortion; the
//! model is built from the photo and box as `photopose model` builds it.
//!
//! `suite_scenes` (ignored: `cargo test --test integration -- --ignored --nocapture
//! suite_scenes`) estimates them all, reports the accuracy targets (reached or not) and
//! asserts that no pose more than 20 mm or 10° off is reported found and that the
//! success shares stay at their floors; the other tests check that the scenes are what
//! they claim.

pub mod edit;
mod report;
pub mod table;

use image::RgbImage;
use nalgebra::{Point3, Vector3};
use photopose::camera::calibration::Resolution;
use photopose::camera::Intrinsics;
use photopose::config::Config;
use photopose::estimator::pose::PoseSize;
use photopose::render::{Background, OccluderFill};

use crate::common::data;
use crate::scenes::{self, Rendered, Spec, Stage};

/// Distance of the wall from the left camera, mm (behind every card).
const WALL_MM: f64 = 2000.0;
/// Width of the wall photo on the wall, mm: wider than the view at [`WALL_MM`] (the
/// texture is mirror-repeated beyond it anyway).
const WALL_WIDTH_MM: f64 = 4000.0;

/// A card photo and the box `[x, y, w, h]` the model is built from.
#[derive(Debug, Clone, Copy)]
pub struct Card {
    /// The photo in `tests/data/photos/`.
    pub file: &'static str,
    /// The model's box `[x, y, w, h]`, photo pixels.
    pub bbox: [i64; 4],
}

impl Card {
    /// `file` in `tests/data/photos/` with its box.
    pub const fn new(file: &'static str, bbox: [i64; 4]) -> Self {
        Self { file, bbox }
    }
}

/// A wall patch painted in the card's mean hue and saturation: centred `at` card extents
/// (along the card's x and y image directions, as seen on the wall) from the card's
/// centre, `scale` times the card's size.
#[derive(Debug, Clone, Copy)]
pub struct Patch {
    /// Offset of its centre from the card's, in card lengths and breadths.
    pub at: [f64; 2],
    /// Its size relative to the card's.
    pub scale: f64,
}

/// What the card shows, relative to the photo the model is built from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Texture {
    /// The photo's box, as printed.
    Same,
    /// Hue shifted (OpenCV units) and saturation scaled.
    Recolour {
        /// Added hue, OpenCV units (degrees / 2).
        hue: f64,
        /// Saturation factor.
        sat: f64,
    },
    /// Gaussian blur of this sigma in photo pixels.
    Blurred(f32),
    /// The box moved and resized by `[dx, dy, dw, dh]` photo pixels.
    Recrop([i64; 4]),
}

/// Blur of the rendered frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Blur {
    None,
    /// Gaussian of this sigma, px.
    Defocus(f32),
    /// A stroke of this length (px) along this direction `[x, y]`.
    Motion(f64, [f64; 2]),
}

/// One scene of the suite.
#[derive(Debug, Clone)]
pub struct Case {
    /// Name, card, pose and size, hand-eye, noise, card brightness and occluder share.
    pub spec: Spec,
    /// HD or FHD.
    pub resolution: Resolution,
    /// The wall photo in `tests/data/backgrounds/`.
    pub wall: &'static str,
    /// Same-hue patches painted on the wall.
    pub patches: Vec<Patch>,
    /// What the card shows.
    pub texture: Texture,
    /// Blur of the rendered frame.
    pub blur: Blur,
    /// Per-channel gains `[r, g, b]` on the frame.
    pub gains: [f64; 3],
    /// The occluder's colour (if `spec.occluder > 0`).
    pub occluder_colour: [u8; 3],
}

/// A scene at HD (see [`Case::fhd`]): `card` on `wall`, at `position` (mm) turned by `rotation_deg` (about
/// x, then y, then z) in the left-camera frame, `length` mm long, its breadth by the
/// photo box's aspect.
pub fn scene(
    name: &'static str,
    card: Card,
    wall: &'static str,
    position: [f64; 3],
    rotation_deg: [f64; 3],
    length: f64,
) -> Case {
    let [_, _, w, h] = card.bbox;
    Case {
        spec: Spec {
            name,
            photo: card.file,
            bbox: card.bbox,
            position,
            rotation_deg,
            size_mm: [length, length * h as f64 / w as f64],
            hand_eye: false,
            noise: 0.0,
            brightness: 1.0,
            occluder: 0.0,
        },
        resolution: Resolution::HD,
        wall,
        patches: Vec::new(),
        texture: Texture::Same,
        blur: Blur::None,
        gains: [1.0; 3],
        occluder_colour: [128; 3],
    }
}

/// The table's modifiers.
impl Case {
    /// At FHD instead of HD.
    pub fn fhd(mut self) -> Self {
        self.resolution = Resolution::FHD;
        self
    }
    /// Breadth × `k`: the card's aspect differs from the photo box's.
    pub fn stretch(mut self, k: f64) -> Self {
        self.spec.size_mm[1] *= k;
        self
    }
    /// Seen through the non-identity hand-eye transform [`scenes::hand_eye`].
    pub fn hand_eye(mut self) -> Self {
        self.spec.hand_eye = true;
        self
    }
    /// Gaussian pixel noise of this sigma, grey levels.
    pub fn noise(mut self, sigma: f64) -> Self {
        self.spec.noise = sigma;
        self
    }
    /// The card's light × `brightness`.
    pub fn light(mut self, brightness: f64) -> Self {
        self.spec.brightness = brightness;
        self
    }
    /// An occluder of `colour` hiding `fraction` of the card.
    pub fn occluded(mut self, fraction: f64, colour: [u8; 3]) -> Self {
        self.spec.occluder = fraction;
        self.occluder_colour = colour;
        self
    }
    /// White balance gains on the frame.
    pub fn wb(mut self, gains: [f64; 3]) -> Self {
        self.gains = gains;
        self
    }
    /// Blur of the frame.
    pub fn blur(mut self, blur: Blur) -> Self {
        self.blur = blur;
        self
    }
    /// A same-hue patch on the wall.
    pub fn paint(mut self, patch: Patch) -> Self {
        self.patches.push(patch);
        self
    }
    /// What the card shows.
    pub fn texture(mut self, texture: Texture) -> Self {
        self.texture = texture;
        self
    }

    /// Any noise, blur, change of light or white balance, or an occluder.
    pub fn hard(&self) -> bool {
        self.spec.hard() || self.blur != Blur::None || self.gains != [1.0; 3]
    }
}

/// Renders `case` (seeded) and builds its model.
pub fn render(case: &Case, seed: u64) -> Rendered {
    let config = scenes::config(&case.spec);
    let model = scenes::model(&case.spec, &config);
    let stage = Stage {
        resolution: case.resolution,
        texture: card_texture(case),
        background: wall(case, model.mean_hue, model.mean_saturation),
        occluder_fill: OccluderFill::Solid(case.occluder_colour),
    };
    scenes::render_staged(&case.spec, seed, stage, |images| {
        if case.gains != [1.0; 3] {
            edit::white_balance(images, case.gains);
        }
        match case.blur {
            Blur::None => {}
            Blur::Defocus(sigma) => edit::defocus(images, sigma),
            Blur::Motion(length, dir) => edit::motion(images, length, dir),
        }
    })
}

/// The card's texture: the photo's box, or the altered copy the case asks for.
fn card_texture(case: &Case) -> RgbImage {
    let full = scenes::photo(case.spec.photo);
    let bbox = case.spec.bbox;
    match case.texture {
        Texture::Same => scenes::crop(&full, bbox),
        Texture::Recolour { hue, sat } => edit::recolour(&scenes::crop(&full, bbox), hue, sat),
        Texture::Blurred(sigma) => image::imageops::blur(&scenes::crop(&full, bbox), sigma),
        Texture::Recrop(d) => scenes::crop(&full, std::array::from_fn(|i| bbox[i] + d[i])),
    }
}

fn load_wall(file: &str) -> RgbImage {
    image::open(data(format!("backgrounds/{file}")))
        .expect("wall photo")
        .to_rgb8()
}

/// The wall: the case's photo, [`WALL_WIDTH_MM`] wide at [`WALL_MM`], with its patches
/// painted in `hue` and `sat`.
fn wall(case: &Case, hue: f64, sat: f64) -> Background {
    let mut texture = load_wall(case.wall);
    let texel_mm = WALL_WIDTH_MM / texture.width() as f64;
    let (w, h) = (texture.width() as f64, texture.height() as f64);
    let [x, y, z] = case.spec.position;
    let on_wall = WALL_MM / z;
    let card = case.spec.size_mm.map(|s| s * on_wall / texel_mm);
    let centre = [x * on_wall / texel_mm + 0.5 * w, y * on_wall / texel_mm + 0.5 * h];
    for p in &case.patches {
        let size = card.map(|c| c * p.scale);
        let c = [centre[0] + p.at[0] * card[0], centre[1] + p.at[1] * card[1]];
        let rect = [c[0] - 0.5 * size[0], c[1] - 0.5 * size[1], size[0], size[1]].map(|v| v.round() as i64);
        edit::paint_hue(&mut texture, rect, hue, sat);
    }
    Background::from_texture(&texture, WALL_MM, texel_mm)
}

/// What a scene looks like to the cameras, from its geometry alone.
#[derive(Debug, Clone, Copy)]
pub struct Geometry {
    /// The card's larger bounding-box side in the left image, px.
    pub extent_px: f64,
    /// Share of the card inside each image (left, right), before occlusion.
    pub in_view: [f64; 2],
    /// Angle between the card's normal and the left camera's optical axis, degrees.
    pub tilt_deg: f64,
}

/// The card's projection into both cameras of `case`'s rig.
pub fn geometry(case: &Case, config: &Config) -> Geometry {
    let rig = config.calibration.rig(case.resolution).expect("calibrated resolution");
    let left_from_model = scenes::left_from_model(&case.spec);
    let [l, b] = case.spec.size_mm;
    const N: usize = 40;
    let points: Vec<Point3<f64>> = (0..=N)
        .flat_map(|i| (0..=N).map(move |j| (i, j)))
        .map(|(i, j)| {
            left_from_model * Point3::new(l * (i as f64 / N as f64 - 0.5), b * (j as f64 / N as f64 - 0.5), 0.0)
        })
        .collect();
    let inside = |cam: &Intrinsics, p: &Point3<f64>| {
        cam.project(p)
            .filter(|q| (0.0..rig.width as f64).contains(&q.x) && (0.0..rig.height as f64).contains(&q.y))
    };
    let share = |hits: usize| hits as f64 / points.len() as f64;
    let left: Vec<_> = points.iter().filter_map(|p| inside(&rig.left, p)).collect();
    let right = points
        .iter()
        .filter(|p| inside(&rig.right, &(rig.right_from_left * *p)).is_some())
        .count();
    let span = |f: fn(&nalgebra::Point2<f64>) -> f64| {
        let (lo, hi) = left
            .iter()
            .map(f)
            .fold((f64::MAX, f64::MIN), |(lo, hi), v| (lo.min(v), hi.max(v)));
        hi - lo
    };
    let normal = left_from_model.rotation * Vector3::z();
    Geometry {
        extent_px: span(|q| q.x).max(span(|q| q.y)),
        in_view: [share(left.len()), share(right)],
        tilt_deg: normal.z.abs().clamp(0.0, 1.0).acos().to_degrees(),
    }
}

/// The truth as a candidate of the search.
pub fn truth(r: &Rendered) -> PoseSize {
    PoseSize::from_pose(&r.hand_from_model, r.spec.size_mm, r.model.l_p, r.model.b_p)
}

/// The seed `case` number `i` is rendered with.
pub fn seed(i: usize) -> u64 {
    1000 + i as u64
}

/// Estimates one rendered scene in the robust and the paper mode and scores the truth.
fn estimate(case: &Case, r: &Rendered) -> report::Row {
    use photopose::estimator::settings::Mode;
    let start = std::time::Instant::now();
    let (robust, outcome) = crate::accuracy::run(r, Mode::Robust);
    let seconds = start.elapsed().as_secs_f64();
    let truth = photopose::estimator::oneshot::score_at(&r.model, &r.images, &r.config, &truth(r)).expect("calibrated");
    report::Row {
        name: case.spec.name,
        hard: case.hard(),
        resolution: case.resolution.name(),
        extent_px: geometry(case, &r.config).extent_px,
        robust,
        paper: crate::accuracy::run(r, Mode::Paper).0,
        score_result: outcome.fitness.score,
        score_truth: truth.score,
        seconds,
        verdict: outcome.verdict,
    }
}

/// The accuracy suite (`cargo test --test integration -- --ignored --nocapture
/// suite_scenes`): every scene in the robust and the paper mode with the configured
/// generations and seed (about 2 s a scene on 2 cores); prints the table and the
/// summary, writes them to `target/suite/suite.md`, reports the targets and asserts
/// the verdict's promise and the floors (on the robust mode; the paper mode is shown for
/// comparison).
#[test]
#[ignore = "about 6 minutes of estimates; CI runs it (see .ci/run)"]
fn suite_scenes() {
    // `SCENES=cup-room,astro-dogs` runs only those scenes, `SEARCH_SEED=2` searches
    // from another seed than the configured one (either: no file, no floors).
    let only = std::env::var("SCENES").ok();
    let search_seed: Option<u64> = std::env::var("SEARCH_SEED")
        .ok()
        .map(|s| s.parse().expect("SEARCH_SEED is a whole number"));
    let chosen = |c: &Case| only.as_deref().is_none_or(|o| o.split(',').any(|n| n == c.spec.name));
    let start = std::time::Instant::now();
    let cases = table::all();
    let lines = report::table(&[]);
    println!("\n{}\n{}", lines[0], lines[1]);
    let mut rows = Vec::new();
    for (i, case) in cases.iter().enumerate().filter(|(_, c)| chosen(c)) {
        let mut r = render(case, seed(i));
        r.config.ga.seed = search_seed.unwrap_or(r.config.ga.seed);
        rows.push(estimate(case, &r));
        println!("{}", report::table(&rows[rows.len() - 1..])[2]);
    }
    let seconds = start.elapsed().as_secs_f64();
    println!();
    for line in report::summary_lines(&rows, seconds) {
        println!("{line}");
    }
    if only.is_some() || search_seed.is_some() {
        report::assert_verdict(&rows);
        return;
    }
    report::write_markdown(&rows, seconds);
    for line in report::target_lines(&rows) {
        println!("{line}");
    }
    report::assert_promises(&rows);
}

/// Frames without the object: the first scene on each wall, estimated with the models
/// of two other photos (the card in view is then a distractor). The verdict must call
/// none of them found; every search of a frame without the object is retried, so each
/// takes all of them. CI runs it with the suite (the `suite_scenes` filter).
#[test]
#[ignore = "about 4 minutes of estimates; CI runs it (see .ci/run)"]
fn suite_scenes_without_the_object_are_not_found() {
    use photopose::estimator::oneshot;
    let cases = table::all();
    let mut photos: Vec<(&str, [i64; 4])> = Vec::new();
    for c in &cases {
        if !photos.iter().any(|p| p.0 == c.spec.photo) {
            photos.push((c.spec.photo, c.spec.bbox));
        }
    }
    let (mut walls, mut found) = (Vec::new(), Vec::new());
    for (i, case) in cases.iter().enumerate() {
        if walls.contains(&case.wall) {
            continue;
        }
        walls.push(case.wall);
        let r = render(case, seed(i));
        let others: Vec<_> = photos.iter().filter(|p| p.0 != case.spec.photo).collect();
        for other in [
            others[walls.len() % others.len()],
            others[(walls.len() + 2) % others.len()],
        ] {
            let spec = Spec {
                photo: other.0,
                bbox: other.1,
                ..case.spec.clone()
            };
            let model = scenes::model(&spec, &r.config);
            let (generations, seed) = (r.config.ga.generations, r.config.ga.seed);
            let out = oneshot::run(&model, &r.images, &r.config, generations, seed, &mut |_| {}).expect("calibrated");
            let v = &out.verdict;
            let line = format!(
                "{} model of {}: {}, confidence {:.2}, {} searches",
                case.spec.name,
                other.0,
                if v.found { "FOUND" } else { "not found" },
                v.confidence,
                out.searches
            );
            println!("{line}");
            if v.found {
                found.push(line);
            }
        }
    }
    assert!(found.is_empty(), "found where the object is not: {found:#?}");
}

/// The scenes are what the suite claims: enough of them, of each kind; every card is
/// (at least 75 %) in view of both eyes, 45–420 px large, tilted at most 45°, and its
/// truth lies inside the default search space; every scene renders.
#[test]
fn suite_scenes_are_as_described() {
    let cases = table::all();
    let hard = cases.iter().filter(|c| c.hard()).count();
    assert!(
        cases.len() >= 44 && hard >= 18 && cases.len() - hard >= 22,
        "{} scenes, {hard} hard",
        cases.len()
    );
    let mut names: Vec<&str> = cases.iter().map(|c| c.spec.name).collect();
    names.sort_unstable();
    names.dedup();
    assert_eq!(names.len(), cases.len(), "scene names repeat");
    for (i, case) in cases.iter().enumerate() {
        let config = scenes::config(&case.spec);
        let g = geometry(case, &config);
        let name = case.spec.name;
        let visible = g.in_view.map(|v| v * (1.0 - case.spec.occluder));
        assert!(visible.iter().all(|&v| v >= 0.75), "{name}: visible {visible:?}");
        assert!((45.0..=420.0).contains(&g.extent_px), "{name}: {:.0} px", g.extent_px);
        assert!(g.tilt_deg <= 45.0 + 1e-9, "{name}: tilt {:.1}°", g.tilt_deg);
        let r = render(case, seed(i));
        assert_eq!(r.images.eye_size(), case.resolution.size(), "{name}");
        assert_inside_search_space(name, &truth(&r), &r);
        if std::env::var_os("SUITE_FRAMES").is_some() {
            save_frame(&r);
        }
    }
}

/// Writes the frame of `r` to `target/suite/frames/NAME.jpg` (with `SUITE_FRAMES` set,
/// to look at the scenes).
fn save_frame(r: &Rendered) {
    let dir = crate::common::repo("target/suite/frames");
    std::fs::create_dir_all(&dir).unwrap();
    r.images
        .to_sbs()
        .save(dir.join(format!("{}.jpg", r.spec.name)))
        .unwrap();
}

/// The truth is a candidate of the default search space.
fn assert_inside_search_space(name: &str, t: &PoseSize, r: &Rendered) {
    let s = &r.config.search;
    let within = |v: f64, [lo, hi]: [f64; 2]| (lo..=hi).contains(&v);
    let [length, _] = t.size_mm(r.model.l_p, r.model.b_p);
    let p = t.position;
    assert!(
        within(p.x, s.x_mm) && within(p.y, s.y_mm) && within(p.z, s.z_mm),
        "{name}: truth at {p:?} mm (hand frame)"
    );
    assert!(within(length, s.size_mm), "{name}: length {length:.0} mm");
    assert!(within(t.k, s.aspect_k), "{name}: aspect k {:.2}", t.k);
}

/// `oneshot::score_at` scores on the problem `oneshot::run` searches: the best
/// individual's score is the outcome's, and the truth outscores a pose 20 mm beside it.
#[test]
fn score_at_ranks_like_the_search() {
    use photopose::estimator::oneshot::{run, score_at};
    let cases = table::all();
    let r = render(&cases[0], seed(0));
    let out = run(&r.model, &r.images, &r.config, 30, 1, &mut |_| {}).unwrap();
    let again = score_at(&r.model, &r.images, &r.config, &out.best).unwrap();
    assert!(
        (again.score - out.fitness.score).abs() < 1e-9,
        "{again:?} vs {:?}",
        out.fitness
    );
    let t = truth(&r);
    let beside = PoseSize {
        position: t.position + Vector3::new(20.0, 0.0, 0.0),
        ..t
    };
    let [at, off] = [t, beside].map(|p| score_at(&r.model, &r.images, &r.config, &p).unwrap().score);
    assert!(at > off, "truth {at:.3}, 20 mm beside it {off:.3}");
}

/// The last retries' dense scan (`Problem::scan_dense`): on `cat-room-fhd-defocus`, a
/// 152 px cat card on a room of its fur's colours, none of the plain scan's regions is
/// within 40 mm of the truth (colour alone ranks the card's placements below the
/// wall's); the dense scan, ranking by the structure term as well on a finer grid of
/// sizes and rolls, has its best region there.
#[test]
fn the_dense_scan_finds_a_card_on_a_wall_of_its_colours() {
    use photopose::estimator::ga::scan;
    use photopose::estimator::oneshot::Prepared;
    let cases = table::all();
    let (i, case) = cases
        .iter()
        .enumerate()
        .find(|(_, c)| c.spec.name == "cat-room-fhd-defocus")
        .expect("the scene is in the suite");
    let r = render(case, seed(i));
    let prepared = Prepared::new(&r.model, &r.images, &r.config).expect("calibrated");
    let t = truth(&r).position;
    let distances = |dense: bool| -> Vec<f64> {
        let mut problem = prepared.problem(&r.config);
        problem.scan_dense = dense;
        let regions = scan::seeds(&problem, 40).regions;
        regions
            .iter()
            .map(|g| (problem.bounds.decode(g).position - t).norm())
            .collect()
    };
    let plain = distances(false);
    let nearest = plain.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(nearest > 40.0, "a plain region came {nearest:.0} mm near");
    let dense = distances(true);
    assert!(dense[0] < 20.0, "the best dense region is {:.0} mm off", dense[0]);
}
