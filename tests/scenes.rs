//! The rendered test scenes: real photos on cards in front of a cluttered collage
//! wall, through the example ZED 2i calibration at HD with lens distortion.

use std::path::Path;

use image::RgbImage;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use photopose::camera::calibration::Resolution;
use photopose::config::Config;
use photopose::estimator::model::PhotoModel;
use photopose::render::{self, Background, Card, Scene};
use photopose::vision::frame::{load_rgb, StereoImages};

use crate::common::data;

/// Photos shipped for tests (public domain / CC0, from scikit-image's sample data).
pub const PHOTOS: [&str; 4] = ["coffee.jpg", "chelsea.jpg", "astronaut.jpg", "rocket.jpg"];

/// One scene: which photo and box, where the card is in the left-camera frame.
#[derive(Debug, Clone)]
pub struct Spec {
    pub name: &'static str,
    pub photo: &'static str,
    pub bbox: [i64; 4],
    /// Card centre in the left camera frame, mm.
    pub position: [f64; 3],
    /// Intrinsic rotations about x, then y, then z, degrees (0 = facing the camera).
    pub rotation_deg: [f64; 3],
    pub size_mm: [f64; 2],
    /// Non-identity hand-eye transform.
    pub hand_eye: bool,
    pub noise: f64,
    pub brightness: f64,
    pub occluder: f64,
}

impl Spec {
    pub fn hard(&self) -> bool {
        self.noise > 0.0 || self.occluder > 0.0 || self.brightness != 1.0
    }
}

const CUP: [i64; 4] = [149, 22, 279, 289];
const CAT: [i64; 4] = [70, 20, 280, 270];
const ASTRONAUT: [i64; 4] = [120, 20, 270, 330];
const ROCKET: [i64; 4] = [150, 60, 340, 300];

const fn spec(
    name: &'static str,
    photo: &'static str,
    bbox: [i64; 4],
    position: [f64; 3],
    rotation_deg: [f64; 3],
    size_mm: [f64; 2],
) -> Spec {
    Spec {
        name,
        photo,
        bbox,
        position,
        rotation_deg,
        size_mm,
        hand_eye: false,
        noise: 0.0,
        brightness: 1.0,
        occluder: 0.0,
    }
}

/// The accuracy suite: clean scenes first, then noisy, dim or occluded ones.
pub fn all() -> Vec<Spec> {
    vec![
        spec(
            "cup-600",
            "coffee.jpg",
            CUP,
            [30.0, 20.0, 600.0],
            [10.0, -5.0, 0.0],
            [100.0, 104.0],
        ),
        spec(
            "cup-900-tilt",
            "coffee.jpg",
            CUP,
            [-120.0, 40.0, 900.0],
            [25.0, 0.0, 5.0],
            [200.0, 207.0],
        ),
        spec(
            "cup-450-aspect",
            "coffee.jpg",
            CUP,
            [20.0, -30.0, 450.0],
            [0.0, 8.0, 0.0],
            [60.0, 80.0],
        ),
        spec(
            "cat-700",
            "chelsea.jpg",
            CAT,
            [60.0, 0.0, 700.0],
            [-15.0, 15.0, 0.0],
            [150.0, 145.0],
        ),
        spec(
            "cat-1000-35",
            "chelsea.jpg",
            CAT,
            [-50.0, -60.0, 1000.0],
            [0.0, 35.0, 0.0],
            [250.0, 240.0],
        ),
        spec(
            "cat-500-roll",
            "chelsea.jpg",
            CAT,
            [0.0, 40.0, 500.0],
            [5.0, 0.0, 30.0],
            [80.0, 77.0],
        ),
        spec(
            "astro-800",
            "astronaut.jpg",
            ASTRONAUT,
            [-80.0, 30.0, 800.0],
            [0.0, -20.0, 0.0],
            [120.0, 147.0],
        ),
        spec(
            "astro-400",
            "astronaut.jpg",
            ASTRONAUT,
            [10.0, 10.0, 400.0],
            [15.0, 0.0, -10.0],
            [50.0, 61.0],
        ),
        spec(
            "rocket-650-30",
            "rocket.jpg",
            ROCKET,
            [40.0, -20.0, 650.0],
            [30.0, 0.0, 0.0],
            [180.0, 159.0],
        ),
        Spec {
            hand_eye: true,
            ..spec(
                "cup-handeye",
                "coffee.jpg",
                CUP,
                [-40.0, 20.0, 750.0],
                [-10.0, 20.0, 0.0],
                [120.0, 124.0],
            )
        },
        Spec {
            hand_eye: true,
            ..spec(
                "cat-handeye",
                "chelsea.jpg",
                CAT,
                [70.0, -30.0, 850.0],
                [20.0, 0.0, -15.0],
                [180.0, 200.0],
            )
        },
        Spec {
            hand_eye: true,
            ..spec(
                "rocket-handeye",
                "rocket.jpg",
                ROCKET,
                [0.0, 50.0, 950.0],
                [0.0, -25.0, 10.0],
                [220.0, 194.0],
            )
        },
        // Noisy, dimmed or occluded.
        Spec {
            noise: 8.0,
            brightness: 0.8,
            ..spec(
                "cup-noise-dim",
                "coffee.jpg",
                CUP,
                [50.0, 0.0, 650.0],
                [12.0, 10.0, 0.0],
                [110.0, 114.0],
            )
        },
        Spec {
            occluder: 0.2,
            ..spec(
                "cat-occluded",
                "chelsea.jpg",
                CAT,
                [-30.0, 20.0, 600.0],
                [0.0, -20.0, 0.0],
                [130.0, 125.0],
            )
        },
        Spec {
            noise: 6.0,
            occluder: 0.15,
            hand_eye: true,
            ..spec(
                "astro-noise-occl",
                "astronaut.jpg",
                ASTRONAUT,
                [30.0, -20.0, 700.0],
                [10.0, 15.0, 0.0],
                [110.0, 134.0],
            )
        },
        Spec {
            noise: 5.0,
            brightness: 1.2,
            ..spec(
                "rocket-bright",
                "rocket.jpg",
                ROCKET,
                [-60.0, 10.0, 800.0],
                [-20.0, 10.0, 0.0],
                [160.0, 141.0],
            )
        },
    ]
}

/// The hand-eye transform of the `hand_eye` scenes: camera 40 mm right, 60 mm up and
/// 120 mm in front of the hand, turned 10° about z and 5° about x.
pub fn hand_eye() -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(40.0, -60.0, 120.0),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 10f64.to_radians())
            * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 5f64.to_radians()),
    )
}

pub fn rotation(deg: [f64; 3]) -> UnitQuaternion<f64> {
    UnitQuaternion::from_axis_angle(&Vector3::x_axis(), deg[0].to_radians())
        * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), deg[1].to_radians())
        * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), deg[2].to_radians())
}

/// A rendered scene with everything needed to estimate and score it.
pub struct Rendered {
    pub spec: Spec,
    pub config: Config,
    pub model: PhotoModel,
    pub images: StereoImages,
    /// Ground truth `H_T_M`.
    pub hand_from_model: Isometry3<f64>,
}

pub fn photo(name: &str) -> RgbImage {
    load_rgb(&data(format!("photos/{name}"))).expect("test photo")
}

/// How a scene is shot, beyond its [`Spec`]: the resolution, what the card shows, the
/// wall behind it and the occluder's look.
pub struct Stage {
    pub resolution: Resolution,
    /// The card's texture (the photo's box crop, or an altered copy of it).
    pub texture: RgbImage,
    pub background: Background,
    pub occluder_fill: render::OccluderFill,
}

/// The card frame Σ_M in the left-camera frame.
pub fn left_from_model(spec: &Spec) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(spec.position[0], spec.position[1], spec.position[2]),
        rotation(spec.rotation_deg),
    )
}

/// The built-in configuration, with the [`hand_eye`] transform if the scene asks for it.
pub fn config(spec: &Spec) -> Config {
    let mut config = Config::load(None).expect("built-in config");
    if spec.hand_eye {
        config.left_from_hand = hand_eye();
    }
    config
}

/// The box `[x, y, w, h]` of `full`.
pub fn crop(full: &RgbImage, [x, y, w, h]: [i64; 4]) -> RgbImage {
    image::imageops::crop_imm(full, x as u32, y as u32, w as u32, h as u32).to_image()
}

/// The photo-model of the scene's photo and box, built as `photopose model --photo P
/// --box x,y,w,h` builds it.
pub fn model(spec: &Spec, config: &Config) -> PhotoModel {
    let path = data(format!("photos/{}", spec.photo));
    let full = load_rgb(&path).expect("test photo");
    PhotoModel::build(&full, &path, spec.bbox, &config.model, &config.fitness.classes()).expect("model")
}

/// Renders a scene at HD in front of a collage of the other photos and builds the
/// photo-model from the same photo and box.
pub fn render(spec: &Spec, seed: u64) -> Rendered {
    let background_photos: Vec<RgbImage> = PHOTOS.iter().filter(|p| **p != spec.photo).map(|p| photo(p)).collect();
    let stage = Stage {
        resolution: Resolution::HD,
        texture: crop(&photo(spec.photo), spec.bbox),
        background: Background::collage(&background_photos, seed, 1600.0),
        occluder_fill: render::OccluderFill::Solid([90, 110, 60]),
    };
    render_staged(spec, seed, stage, |_| {})
}

/// Renders `spec` as `stage` says through the example calibration (with its lens
/// distortion), applies `post` to both eyes' images, and builds the photo-model.
pub fn render_staged(spec: &Spec, seed: u64, stage: Stage, post: impl FnOnce(&mut StereoImages)) -> Rendered {
    let config = config(spec);
    let rig = config.calibration.rig(stage.resolution).expect("calibrated resolution");
    let left_from_model = left_from_model(spec);
    let hand_from_model = config.left_from_hand.inverse() * left_from_model;
    let scene = Scene {
        card: Card {
            texture: stage.texture,
            hand_from_model,
            size_mm: spec.size_mm,
        },
        background: stage.background,
        noise_sigma: spec.noise,
        brightness: spec.brightness,
        occluder: render::Occluder::covering(&left_from_model, spec.size_mm, spec.occluder, stage.occluder_fill, seed),
        seed,
    };
    let sbs = render::render(&rig, &config.left_from_hand, &scene);
    let mut images = StereoImages::from_sbs(&sbs, Path::new(spec.name)).expect("even width");
    post(&mut images);
    let model = model(spec, &config);
    Rendered {
        spec: spec.clone(),
        config,
        model,
        images,
        hand_from_model,
    }
}
