//! Filming a scenario: each frame rendered at sub-frame times across the exposure and
//! averaged (motion blur), then the light's gains and pixel noise, as RGB8 or YUYV; the
//! truth and the share of the card in view; and the whole take written as a recorded
//! sequence.

use std::path::Path;

use nalgebra::{Isometry3, Point3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use super::{InView, Judged, Scenario};
use crate::camera::calibration::Resolution;
use crate::camera::StereoRig;
use crate::capture::record::Recorder;
use crate::capture::sequence::SequenceError;
use crate::capture::{FrameInfo, Geometry, Truth};
use crate::config::Config;
use crate::estimator::model::PhotoModel;
use crate::estimator::pose::rotation_error_deg;
use crate::render::{Background, Card, Occluder, Renderer, Scene};
use crate::vision::color::yuyv_from_rgb;
use crate::vision::frame::load_rgb;
use crate::vision::PixelFormat;

/// Sub-frames averaged over the exposure of a blurred frame.
const SUBFRAMES: usize = 5;
/// The wall: the photo 4 m wide, 2 m from the camera.
const WALL_MM: f64 = 2000.0;
const WALL_WIDTH_MM: f64 = 4000.0;

/// A scenario on the stage: its scene (card and wall), the camera, and the renderer.
pub struct Film {
    scenario: Scenario,
    rig: StereoRig,
    left_from_hand: Isometry3<f64>,
    scene: Scene,
    renderer: Renderer,
    /// Sub-frame scratch and the exposure's sum.
    scratch: Vec<u8>,
    sum: Vec<f32>,
}

impl Film {
    /// Sets up `scenario` for `config`'s HD calibration and hand–eye transform; its
    /// photos are read under `root` (the repository's root). Fails with one line naming
    /// a photo that cannot be read.
    pub fn new(scenario: &Scenario, root: &Path, config: &Config) -> Result<Self, String> {
        let read = |rel: &str| {
            let path = root.join(rel);
            load_rgb(&path).map_err(|e| format!("{e} (scenarios read the repository's test photos: run from its root)"))
        };
        let photo = read(scenario.card.photo)?;
        let wall = read(scenario.wall)?;
        let [x, y, w, h] = scenario.card.bbox;
        if x + w > photo.width() || y + h > photo.height() {
            return Err(format!("{}: the box lies outside the photo", scenario.card.photo));
        }
        let rig = config.calibration.rig(Resolution::HD).map_err(|e| e.to_string())?;
        let scene = Scene {
            card: Card {
                texture: image::imageops::crop_imm(&photo, x, y, w, h).to_image(),
                hand_from_model: Isometry3::identity(),
                size_mm: scenario.size_mm(),
            },
            background: Background::from_texture(&wall, WALL_MM, WALL_WIDTH_MM / wall.width() as f64),
            noise_sigma: 0.0,
            brightness: 1.0,
            occluder: None,
            seed: 0,
        };
        let renderer = Renderer::new(&rig, &config.left_from_hand, &scene);
        Ok(Self {
            scenario: scenario.clone(),
            left_from_hand: config.left_from_hand,
            scratch: vec![0; renderer.frame_len()],
            sum: vec![0.0; renderer.frame_len()],
            rig,
            scene,
            renderer,
        })
    }

    /// The photo-model of the scenario's photo and box, built as `photopose model
    /// --photo P --box x,y,w,h` builds it.
    pub fn model(scenario: &Scenario, root: &Path, config: &Config) -> Result<PhotoModel, String> {
        let path = root.join(scenario.card.photo);
        let photo = load_rgb(&path).map_err(|e| e.to_string())?;
        let [x, y, w, h] = scenario.card.bbox.map(i64::from);
        PhotoModel::build(&photo, &path, [x, y, w, h], &config.model, &config.fitness.classes())
            .map_err(|e| format!("{}: {e}", path.display()))
    }

    /// The camera.
    pub fn rig(&self) -> &StereoRig {
        &self.rig
    }

    /// The frames' layout: HD, RGB8 or YUYV as the scenario sends them.
    pub fn geometry(&self) -> Geometry {
        Geometry {
            width: self.rig.width,
            height: self.rig.height,
            format: if self.scenario.yuyv {
                PixelFormat::Yuyv
            } else {
                PixelFormat::Rgb8
            },
        }
    }

    /// The time of frame `i`, s.
    pub fn time(&self, i: usize) -> f64 {
        i as f64 / self.scenario.fps
    }

    /// The card in the left camera's frame at time `t`, and what stands in front of it.
    fn staged(&self, t: f64) -> (Isometry3<f64>, Option<Occluder>) {
        let left_from_model = (self.scenario.motion)(t);
        let occluder = (self.scenario.occluder)(t, &left_from_model, self.scene.card.size_mm);
        (left_from_model, occluder)
    }

    /// The truth of frame `i`: the card's pose in the hand frame and its size.
    pub fn truth(&self, i: usize) -> Truth {
        let (left_from_model, _) = self.staged(self.time(i));
        Truth {
            hand_from_model: self.left_from_hand.inverse() * left_from_model,
            size_mm: self.scene.card.size_mm,
        }
    }

    /// Share of the card the left camera sees in frame `i`.
    pub fn visible(&self, i: usize) -> f64 {
        self.in_view(i).left
    }

    /// Shares of the card the left camera and both cameras see in frame `i`.
    pub fn in_view(&self, i: usize) -> InView {
        let (left_from_model, occluder) = self.staged(self.time(i));
        visible_share(&self.rig, &left_from_model, self.scene.card.size_mm, occluder.as_ref())
    }

    /// Judges an estimate of frame `i` (the card in the hand frame and its size).
    pub fn judge(&self, i: usize, hand_from_model: &Isometry3<f64>, size_mm: [f64; 2], tracking: bool) -> Judged {
        let truth = self.truth(i);
        let rel = |k: usize| (size_mm[k] - truth.size_mm[k]).abs() / truth.size_mm[k];
        Judged {
            in_view: self.in_view(i),
            tracking,
            errors: [
                (hand_from_model.translation.vector - truth.hand_from_model.translation.vector).norm(),
                rel(0).max(rel(1)),
                rotation_error_deg(&hand_from_model.rotation, &truth.hand_from_model.rotation),
            ],
        }
    }

    /// Frame `i` as the camera sends it ([`Film::geometry`]).
    pub fn frame(&mut self, i: usize) -> Vec<u8> {
        let rgb = self.frame_rgb(i);
        if self.scenario.yuyv {
            yuyv_from_rgb(&rgb, self.rig.width as usize)
        } else {
            rgb
        }
    }

    /// Frame `i` as side-by-side RGB8: the sub-frames across the exposure averaged, then
    /// the light's gains and the noise (seeded by `i`).
    pub fn frame_rgb(&mut self, i: usize) -> Vec<u8> {
        let t = self.time(i);
        let exposure = self.scenario.exposure_s;
        let subs = if exposure > 0.0 { SUBFRAMES } else { 1 };
        self.sum.fill(0.0);
        for k in 0..subs {
            let dt = if subs > 1 {
                exposure * (k as f64 / (subs - 1) as f64 - 0.5)
            } else {
                0.0
            };
            let (left_from_model, occluder) = self.staged(t + dt);
            self.scene.card.hand_from_model = self.left_from_hand.inverse() * left_from_model;
            self.scene.occluder = occluder;
            self.renderer.render_into(&self.scene, &mut self.scratch);
            self.sum
                .iter_mut()
                .zip(&self.scratch)
                .for_each(|(s, &v)| *s += v as f32);
        }
        let gains = (self.scenario.light)(t).map(|g| g as f32 / subs as f32);
        let mut rng = StdRng::seed_from_u64(i as u64);
        let sigma = self.scenario.noise as f32;
        let mut noise = || if sigma > 0.0 { gaussian(&mut rng) * sigma } else { 0.0 };
        (self.sum.iter().enumerate())
            .map(|(j, s)| (s * gains[j % 3] + noise()).round().clamp(0.0, 255.0) as u8)
            .collect()
    }
}

/// A standard normal sample (Box–Muller).
fn gaussian(rng: &mut StdRng) -> f32 {
    let u: f32 = rng.random::<f32>().max(f32::MIN_POSITIVE);
    let v: f32 = rng.random();
    (-2.0 * u.ln()).sqrt() * (std::f32::consts::TAU * v).cos()
}

/// Shares of the card's area (a 20 × 20 grid of points) that the left camera sees, and
/// that both cameras see: inside the image and not behind the occluder.
pub fn visible_share(
    rig: &StereoRig,
    left_from_model: &Isometry3<f64>,
    size_mm: [f64; 2],
    occluder: Option<&Occluder>,
) -> InView {
    const N: usize = 20;
    let (w, h) = (rig.width as f64, rig.height as f64);
    let in_image =
        |q: Option<nalgebra::Point2<f64>>| q.is_some_and(|q| (0.0..w).contains(&q.x) && (0.0..h).contains(&q.y));
    let right_centre = rig.right_from_left.inverse() * Point3::origin();
    let (mut left, mut both) = (0, 0);
    for k in 0..N * N {
        let (i, j) = (k % N, k / N);
        let u = (i as f64 + 0.5) / N as f64 - 0.5;
        let v = (j as f64 + 0.5) / N as f64 - 0.5;
        let p = left_from_model * Point3::new(u * size_mm[0], v * size_mm[1], 0.0);
        let hidden_from = |eye: &Point3<f64>| occluder.is_some_and(|o| hides(o, eye, &p));
        if in_image(rig.left.project(&p)) && !hidden_from(&Point3::origin()) {
            left += 1;
            if in_image(rig.right.project(&(rig.right_from_left * p))) && !hidden_from(&right_centre) {
                both += 1;
            }
        }
    }
    let share = |n: usize| n as f64 / (N * N) as f64;
    InView {
        left: share(left),
        both_eyes: share(both),
    }
}

/// Whether `occluder` lies on the line of sight from the camera centre `eye` (left
/// camera's frame) to `p`.
fn hides(occluder: &Occluder, eye: &Point3<f64>, p: &Point3<f64>) -> bool {
    let to_local = occluder.left_from_occluder.inverse();
    let (o, q) = (to_local * eye, to_local * p);
    if o.z.signum() == q.z.signum() {
        return false;
    }
    let s = o.z / (o.z - q.z);
    let hit = o + (q - o) * s;
    hit.x.abs() <= 0.5 * occluder.size_mm[0] && hit.y.abs() <= 0.5 * occluder.size_mm[1]
}

/// Writes `scenario` into `dir` as a recorded sequence (frame ids from 0, capture times
/// at the take's rate, the truth in the hand frame), rendering on every core;
/// `progress` is told each frame written. Returns each frame's shares of the card in
/// view.
pub fn record(
    scenario: &Scenario,
    root: &Path,
    config: &Config,
    dir: &Path,
    progress: impl Fn(usize),
) -> Result<Vec<InView>, String> {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mut films = (0..threads)
        .map(|_| Film::new(scenario, root, config))
        .collect::<Result<Vec<_>, _>>()?;
    let geometry = films[0].geometry();
    let source = format!("scenario:{}", scenario.name);
    let failed = |e: SequenceError| e.to_string();
    let mut recorder = Recorder::create(dir, geometry, &source).map_err(failed)?;
    let n = scenario.frames();
    let mut visible = Vec::with_capacity(n);
    for batch in (0..n).collect::<Vec<_>>().chunks(threads) {
        let frames = std::thread::scope(|s| {
            let jobs: Vec<_> = (films.iter_mut().zip(batch))
                .map(|(film, &i)| s.spawn(move || film.frame(i)))
                .collect();
            (jobs.into_iter())
                .map(|j| j.join().map_err(|_| "a rendering thread failed".to_string()))
                .collect::<Result<Vec<_>, _>>()
        })?;
        for (&i, bytes) in batch.iter().zip(frames) {
            let film = &films[0];
            let time_ns = (film.time(i) * 1e9).round() as u64;
            let info = FrameInfo::single(time_ns, Some(film.truth(i)));
            recorder.record_all(i as u64, &info, &bytes).map_err(failed)?;
            visible.push(film.in_view(i));
            progress(i + 1);
        }
    }
    recorder.finish().map_err(failed)?;
    Ok(visible)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::capture::sequence::Sequence;

    fn root() -> &'static Path {
        Path::new(env!("CARGO_MANIFEST_DIR"))
    }

    #[test]
    fn a_recorded_scenario_replays_with_its_truth_as_yuyv() {
        let mut take = Scenario::named("yuyv").unwrap();
        take.seconds = 0.1;
        let config = Config::load(None).unwrap();
        let dir = std::env::temp_dir().join(format!("photopose-film-test-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let visible = record(&take, root(), &config, &dir, |_| {}).unwrap();
        let seq = Sequence::open(&dir).unwrap();
        let film = Film::new(&take, root(), &config).unwrap();
        assert_eq!(seq.geometry.format, PixelFormat::Yuyv);
        assert_eq!((seq.geometry.width, seq.geometry.height), (1280, 720));
        assert_eq!(seq.frames.len(), 3);
        for (i, f) in seq.frames.iter().enumerate() {
            assert_eq!(f.frame_id, i as u64);
            assert_eq!(f.capture_time_ns, (i as f64 * 1e9 / 30.0).round() as u64);
            let (got, want) = (f.truth.unwrap(), film.truth(i));
            assert!((got.hand_from_model.translation.vector - want.hand_from_model.translation.vector).norm() < 1e-6);
            assert_eq!(got.size_mm, want.size_mm);
            let bytes = std::fs::metadata(dir.join(&f.file)).unwrap().len();
            assert_eq!(bytes, 2 * 1280 * 720 * 2, "{}: raw YUYV", f.file);
        }
        assert!(
            visible.iter().all(|v| v.left == 1.0 && v.both_eyes == 1.0),
            "{visible:?}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn the_card_leaves_the_view_and_comes_back() {
        let take = Scenario::named("leave").unwrap();
        let film = Film::new(&take, root(), &Config::load(None).unwrap()).unwrap();
        let at = |t: f64| film.visible((t * take.fps).round() as usize);
        assert_eq!(at(0.0), 1.0);
        assert_eq!(at(2.5), 0.0, "out of view from 2 to 3.5 s");
        assert_eq!(at(5.5), 1.0, "back in view");
        // Coming in at the left edge, the card is in the left camera's view about 0.5 s
        // before it is in the right camera's (0.12 m baseline at 0.26 m/s).
        let both = |t: f64| film.in_view((t * take.fps).round() as usize);
        assert!(both(3.9).left == 1.0 && both(3.9).both_eyes < 0.05, "{:?}", both(3.9));
        assert!((0.5..0.7).contains(&both(4.15).both_eyes), "{:?}", both(4.15));
        assert_eq!(both(4.4).both_eyes, 1.0);
    }

    #[test]
    fn motion_blur_smears_the_moving_card_only() {
        let mut take = Scenario::named("sweep").unwrap();
        let config = Config::load(None).unwrap();
        let blurred = Film::new(&take, root(), &config).unwrap().frame(0);
        take.exposure_s = 0.0;
        let sharp = Film::new(&take, root(), &config).unwrap().frame(0);
        let differ = |range: std::ops::Range<usize>| range.filter(|&i| blurred[i] != sharp[i]).count();
        // Frame 0: the card at the middle of the view, moving sideways at 600 mm/s.
        let row = |y: usize| y * 2 * 1280 * 3;
        assert!(differ(row(360)..row(361)) > 30, "the card's edges are smeared");
        assert_eq!(differ(row(5)..row(6)), 0, "the wall, far from the card, is not");
    }
}
