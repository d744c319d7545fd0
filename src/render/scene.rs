//! Scene files (TOML) for the `render` command: the target photo and its pose and size,
//! the background wall and optional effects.
//!
//! ```toml
//! photo = "../../tests/data/photos/coffee.jpg"  # relative to the scene file
//! box = [149, 22, 279, 289]         # x, y, w, h in photo pixels (x, y = top-left)
//! position_mm = [20.0, -10.0, 650.0] # card centre, hand frame
//! rotation_deg = [10.0, -20.0, 5.0]  # intrinsic X-Y-Z Euler angles: R = Rx·Ry·Rz
//! # orientation_wxyz = [1.0, 0.0, 0.0, 0.0]  # alternative to rotation_deg (not both)
//! size_mm = [120.0, 125.0]           # [L, B]: along photo columns, along photo rows
//! resolution = "HD"                  # 2K | FHD | HD | VGA (default HD)
//! [background]                       # optional
//! photos = ["../../tests/data/photos/chelsea.jpg"]
//! distance_mm = 1500.0               # default 1500
//! seed = 7
//! [effects]                          # optional
//! noise_sigma = 0.0                  # grey levels
//! brightness = 1.0                   # card colour factor
//! occluder = 0.0                     # fraction of the card hidden (0 = none, < 1)
//! seed = 1
//! ```
//! Without a rotation the card's model frame is aligned with the hand frame.

use std::path::{Path, PathBuf};

use image::RgbImage;
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use serde::Deserialize;

use super::{Background, Card, Occluder, OccluderFill, Scene};
use crate::camera::calibration::Resolution;
use crate::camera::geometry::{is_unit_wxyz, w_nonnegative, wxyz_norm, FILE_UNIT_TOLERANCE};
use crate::config::toml_error;

/// A scene file that cannot be used; every message is one line naming the file.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene file could not be read.
    #[error("{}: cannot read scene file: {message}", path.display())]
    Read {
        /// The scene file.
        path: PathBuf,
        /// Why.
        message: String,
    },
    /// The scene file is not TOML, or not the keys a scene has.
    #[error("{}: {message}", path.display())]
    Parse {
        /// The scene file.
        path: PathBuf,
        /// `line N, column C: ` and the parser's message.
        message: String,
    },
    /// A value that cannot be rendered.
    #[error("{}: {problem}", path.display())]
    Invalid {
        /// The scene file.
        path: PathBuf,
        /// The key and what is wrong with it.
        problem: String,
    },
    /// A photo the scene names cannot be read.
    #[error("{}: cannot read photo {}: {message}", path.display(), photo.display())]
    Photo {
        /// The scene file.
        path: PathBuf,
        /// The photo, resolved.
        photo: PathBuf,
        /// The decoder's message on one line.
        message: String,
    },
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScene {
    photo: PathBuf,
    #[serde(rename = "box")]
    box_px: [i64; 4],
    position_mm: [f64; 3],
    rotation_deg: Option<[f64; 3]>,
    orientation_wxyz: Option<[f64; 4]>,
    size_mm: [f64; 2],
    resolution: Option<String>,
    #[serde(default)]
    background: RawBackground,
    #[serde(default)]
    effects: RawEffects,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawBackground {
    #[serde(default)]
    photos: Vec<PathBuf>,
    distance_mm: Option<f64>,
    #[serde(default)]
    seed: u64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, default)]
struct RawEffects {
    noise_sigma: f64,
    brightness: f64,
    occluder: f64,
    seed: u64,
}

impl Default for RawEffects {
    fn default() -> Self {
        Self {
            noise_sigma: 0.0,
            brightness: 1.0,
            occluder: 0.0,
            seed: 0,
        }
    }
}

/// Default wall distance, mm.
pub const DEFAULT_BACKGROUND_MM: f64 = 1500.0;

/// A parsed and validated scene file (photo paths resolved, photo sizes checked).
#[derive(Debug, Clone, PartialEq)]
pub struct SceneSpec {
    /// The scene file itself (for messages).
    pub path: PathBuf,
    /// The target photo, resolved.
    pub photo: PathBuf,
    /// `[x, y, w, h]` inside the photo.
    pub box_px: [u32; 4],
    /// The card's pose in the hand frame.
    pub hand_from_model: Isometry3<f64>,
    /// `[L, B]`: the card's extent along the photo's columns and rows, mm.
    pub size_mm: [f64; 2],
    /// The camera resolution to render at (default HD).
    pub resolution: Resolution,
    /// Photos of the background collage, resolved.
    pub background_photos: Vec<PathBuf>,
    /// Distance of the background wall from the left camera, mm.
    pub background_distance_mm: f64,
    /// Seed of the collage's layout.
    pub background_seed: u64,
    /// Standard deviation of the image noise, grey levels.
    pub noise_sigma: f64,
    /// Factor on the card's colours.
    pub brightness: f64,
    /// Fraction of the card hidden by an occluder (0 = none).
    pub occluder_fraction: f64,
    /// Seed of the noise and the occluder.
    pub effects_seed: u64,
}

impl SceneSpec {
    /// Reads, parses and validates a scene file.
    pub fn load(path: &Path) -> Result<Self, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|e| SceneError::Read {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        Self::from_toml_str(&text, path)
    }

    /// Parses and validates scene text as if read from `path` (relative photo paths are
    /// resolved against its directory; photo headers are read to check the box).
    pub fn from_toml_str(text: &str, path: &Path) -> Result<Self, SceneError> {
        let raw: RawScene = toml::from_str(text).map_err(|e| SceneError::Parse {
            path: path.to_path_buf(),
            message: toml_message(text, &e),
        })?;
        let files = SceneFiles { path };
        let invalid = |problem: String| SceneError::Invalid {
            path: path.to_path_buf(),
            problem,
        };
        let photo = files.resolve(&raw.photo);
        let photo_size = files.dimensions(&photo)?;
        let box_px = box_inside(raw.box_px, photo_size, &photo).map_err(invalid)?;
        let hand_from_model =
            hand_from_model(raw.position_mm, raw.rotation_deg, raw.orientation_wxyz).map_err(invalid)?;
        if raw.size_mm.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
            return Err(invalid(format!(
                "size_mm {:?} must be positive and finite",
                raw.size_mm
            )));
        }
        let resolution = match raw.resolution.as_deref() {
            None => Resolution::HD,
            Some(s) => Resolution::from_name(s)
                .ok_or_else(|| invalid(format!("unknown resolution {s:?} (expected 2K, FHD, HD or VGA)")))?,
        };
        let background_photos: Vec<PathBuf> = raw.background.photos.iter().map(|p| files.resolve(p)).collect();
        for p in &background_photos {
            files.dimensions(p)?;
        }
        let distance = raw.background.distance_mm.unwrap_or(DEFAULT_BACKGROUND_MM);
        if !(distance.is_finite() && distance > 0.0) {
            return Err(invalid(format!(
                "background.distance_mm {distance} must be positive and finite"
            )));
        }
        let fx = raw.effects.validate().map_err(invalid)?;
        Ok(Self {
            path: path.to_path_buf(),
            photo,
            box_px,
            hand_from_model,
            size_mm: raw.size_mm,
            resolution,
            background_photos,
            background_distance_mm: distance,
            background_seed: raw.background.seed,
            noise_sigma: fx.noise_sigma,
            brightness: fx.brightness,
            occluder_fraction: fx.occluder,
            effects_seed: fx.seed,
        })
    }

    /// Loads the photos and assembles the [`Scene`] (checks that the card is in front of
    /// the left camera and of the wall). Background photos that are the target's own photo
    /// are left out of the collage.
    pub fn build(&self, left_from_hand: &Isometry3<f64>) -> Result<Scene, SceneError> {
        let invalid = |problem: String| SceneError::Invalid {
            path: self.path.clone(),
            problem,
        };
        let left_from_model = left_from_hand * self.hand_from_model;
        let z = left_from_model.translation.vector.z;
        if z.is_nan() || z <= 0.0 {
            return Err(invalid(format!(
                "the card centre is not in front of the left camera (z = {z:.1} mm in the left-camera frame)"
            )));
        }
        if z >= self.background_distance_mm {
            return Err(invalid(format!(
                "background.distance_mm {} is not behind the card (card centre at z = {z:.1} mm)",
                self.background_distance_mm
            )));
        }
        let photo = self.open(&self.photo)?;
        let [x, y, w, h] = self.box_px;
        let texture = image::imageops::crop_imm(&photo, x, y, w, h).to_image();

        let own = std::fs::canonicalize(&self.photo).unwrap_or_else(|_| self.photo.clone());
        let mut wall_photos = Vec::new();
        for p in &self.background_photos {
            let canon = std::fs::canonicalize(p).unwrap_or_else(|_| p.clone());
            if canon == own {
                tracing::info!("background: leaving out the target photo {}", p.display());
                continue;
            }
            wall_photos.push(self.open(p)?);
        }
        let background = Background::collage(&wall_photos, self.background_seed, self.background_distance_mm);
        let occluder = if self.occluder_fraction > 0.0 {
            let fill = occluder_fill(&wall_photos, self.effects_seed);
            Occluder::covering(
                &left_from_model,
                self.size_mm,
                self.occluder_fraction,
                fill,
                self.effects_seed,
            )
        } else {
            None
        };
        Ok(Scene {
            card: Card {
                texture,
                hand_from_model: self.hand_from_model,
                size_mm: self.size_mm,
            },
            background,
            noise_sigma: self.noise_sigma,
            brightness: self.brightness,
            occluder,
            seed: self.effects_seed,
        })
    }

    fn open(&self, photo: &Path) -> Result<RgbImage, SceneError> {
        image::open(photo).map(|i| i.to_rgb8()).map_err(|e| SceneError::Photo {
            path: self.path.clone(),
            photo: photo.to_path_buf(),
            message: one_line(&e.to_string()),
        })
    }
}

/// The files a scene file names, relative to its directory.
struct SceneFiles<'a> {
    /// The scene file itself.
    path: &'a Path,
}

impl SceneFiles<'_> {
    /// `p` as written if absolute, else relative to the scene file's directory.
    fn resolve(&self, p: &Path) -> PathBuf {
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            self.path.parent().unwrap_or_else(|| Path::new("")).join(p)
        }
    }

    /// A photo's `(width, height)`, read from its header.
    fn dimensions(&self, photo: &Path) -> Result<(u32, u32), SceneError> {
        image::image_dimensions(photo).map_err(|e| SceneError::Photo {
            path: self.path.to_path_buf(),
            photo: photo.to_path_buf(),
            message: one_line(&e.to_string()),
        })
    }
}

/// The target box `[x, y, w, h]` if it has a size and lies inside the `(pw, ph)` photo.
fn box_inside(box_px: [i64; 4], (pw, ph): (u32, u32), photo: &Path) -> Result<[u32; 4], String> {
    let [bx, by, bw, bh] = box_px;
    if bw <= 0 || bh <= 0 {
        return Err(format!("box {box_px:?}: width and height must be positive"));
    }
    if bx < 0 || by < 0 || bx + bw > pw as i64 || by + bh > ph as i64 {
        return Err(format!(
            "box {box_px:?} is not inside the {pw}×{ph} photo {}",
            photo.display()
        ));
    }
    Ok([bx as u32, by as u32, bw as u32, bh as u32])
}

/// The card's pose in the hand frame: a finite position and at most one of Euler angles
/// and a unit quaternion (neither: the identity).
fn hand_from_model(
    position_mm: [f64; 3],
    rotation_deg: Option<[f64; 3]>,
    orientation_wxyz: Option<[f64; 4]>,
) -> Result<Isometry3<f64>, String> {
    if position_mm.iter().any(|v| !v.is_finite()) {
        return Err(format!("position_mm {position_mm:?} is not finite"));
    }
    let rotation = match (rotation_deg, orientation_wxyz) {
        (Some(_), Some(_)) => return Err("give either rotation_deg or orientation_wxyz, not both".into()),
        (Some(e), None) => {
            if e.iter().any(|v| !v.is_finite()) {
                return Err(format!("rotation_deg {e:?} is not finite"));
            }
            euler_xyz_deg(e)
        }
        (None, Some(q)) => {
            if !is_unit_wxyz(q, FILE_UNIT_TOLERANCE) {
                return Err(format!(
                    "orientation_wxyz {q:?} is not a unit quaternion (norm {})",
                    wxyz_norm(q)
                ));
            }
            UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]))
        }
        (None, None) => UnitQuaternion::identity(),
    };
    let [px, py, pz] = position_mm;
    Ok(Isometry3::from_parts(Translation3::new(px, py, pz), rotation))
}

impl RawEffects {
    /// These effects if they can be rendered, else the problem.
    fn validate(self) -> Result<Self, String> {
        if !(self.noise_sigma.is_finite() && self.noise_sigma >= 0.0) {
            return Err(format!(
                "effects.noise_sigma {} must be finite and >= 0",
                self.noise_sigma
            ));
        }
        if !(self.brightness.is_finite() && self.brightness > 0.0) {
            return Err(format!(
                "effects.brightness {} must be positive and finite",
                self.brightness
            ));
        }
        if !(self.occluder.is_finite() && (0.0..1.0).contains(&self.occluder)) {
            return Err(format!(
                "effects.occluder {} must be a fraction in [0, 1)",
                self.occluder
            ));
        }
        Ok(self)
    }
}

/// Ground truth as JSON: `{"position_mm", "orientation_wxyz" (w >= 0), "size_mm", "frame": "hand"}`.
pub fn truth_json(hand_from_model: &Isometry3<f64>, size_mm: [f64; 2]) -> serde_json::Value {
    let t = hand_from_model.translation.vector;
    let q = hand_from_model.rotation.quaternion();
    serde_json::json!({
        "position_mm": [t.x, t.y, t.z],
        "orientation_wxyz": w_nonnegative([q.w, q.i, q.j, q.k]),
        "size_mm": size_mm,
        "frame": "hand",
    })
}

/// Intrinsic X-Y-Z Euler angles in degrees: `R = Rx(a)·Ry(b)·Rz(c)`.
pub fn euler_xyz_deg(e: [f64; 3]) -> UnitQuaternion<f64> {
    UnitQuaternion::from_axis_angle(&Vector3::x_axis(), e[0].to_radians())
        * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), e[1].to_radians())
        * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), e[2].to_radians())
}

/// A crop of one of the wall photos (looks like another object), or a flat colour.
fn occluder_fill(photos: &[RgbImage], seed: u64) -> OccluderFill {
    let mut rng = StdRng::seed_from_u64(seed ^ 0x0cc1_0de5);
    let usable: Vec<&RgbImage> = photos.iter().filter(|p| p.width() >= 4 && p.height() >= 4).collect();
    if usable.is_empty() {
        return OccluderFill::Solid([
            rng.random_range(40..220),
            rng.random_range(40..220),
            rng.random_range(40..220),
        ]);
    }
    let p = usable[rng.random_range(0..usable.len())];
    let (w, h) = (p.width() / 2, p.height() / 2);
    let x = rng.random_range(0..=p.width() - w);
    let y = rng.random_range(0..=p.height() - h);
    OccluderFill::Texture(image::imageops::crop_imm(p, x, y, w, h).to_image())
}

fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// A scene file's TOML error: `line N, column C: message`, the message on one line.
fn toml_message(text: &str, e: &toml::de::Error) -> String {
    let error = toml_error(text, e);
    let message = one_line(error.message);
    match error.line_column {
        Some((line, column)) => format!("line {line}, column {column}: {message}"),
        None => message,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene_path(name: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("config/scenes").join(name)
    }

    const VALID: &str = r#"
photo = "../../tests/data/photos/coffee.jpg"
box = [149, 22, 279, 289]
position_mm = [20.0, -10.0, 650.0]
rotation_deg = [10.0, -20.0, 5.0]
size_mm = [90.0, 93.0]
resolution = "HD"
[background]
photos = ["../../tests/data/photos/chelsea.jpg", "../../tests/data/photos/coffee.jpg"]
distance_mm = 1500.0
seed = 7
[effects]
noise_sigma = 1.5
occluder = 0.2
seed = 3
"#;

    fn parse(text: &str) -> Result<SceneSpec, SceneError> {
        SceneSpec::from_toml_str(text, &scene_path("test.toml"))
    }

    fn err(text: &str) -> String {
        let e = parse(text).expect_err("should fail").to_string();
        assert!(e.contains("test.toml"), "{e}");
        assert!(!e.contains('\n'), "{e}");
        e
    }

    #[test]
    fn valid_scene_parses_and_builds() {
        let s = parse(VALID).unwrap();
        assert_eq!(s.box_px, [149, 22, 279, 289]);
        assert_eq!(s.resolution, Resolution::HD);
        assert_eq!(s.brightness, 1.0);
        let r = s.hand_from_model.rotation;
        let expected = euler_xyz_deg([10.0, -20.0, 5.0]);
        assert!(r.angle_to(&expected) < 1e-12);
        // Intrinsic XYZ: the first rotation is about x.
        let rx = euler_xyz_deg([30.0, 0.0, 0.0]);
        assert!((rx.angle() - 30f64.to_radians()).abs() < 1e-12);
        let scene = s.build(&Isometry3::identity()).unwrap();
        assert_eq!(scene.card.texture.dimensions(), (279, 289));
        assert!(scene.occluder.is_some());
        assert_eq!(scene.seed, 3);
    }

    #[test]
    fn shipped_example_scenes_load() {
        for name in ["coffee.toml", "cat.toml"] {
            let s = SceneSpec::load(&scene_path(name)).unwrap();
            let own = std::fs::canonicalize(&s.photo).unwrap();
            assert!(s
                .background_photos
                .iter()
                .all(|p| std::fs::canonicalize(p).unwrap() != own));
        }
    }

    #[test]
    fn invalid_scenes_name_the_file_and_the_problem() {
        let e = err(&VALID.replace("[149, 22, 279, 289]", "[400, 22, 279, 289]"));
        assert!(e.contains("not inside"), "{e}");
        let e = err(&VALID.replace("[149, 22, 279, 289]", "[149, 22, 0, 289]"));
        assert!(e.contains("positive"), "{e}");
        let e = err(&VALID.replace(
            "rotation_deg = [10.0, -20.0, 5.0]",
            "rotation_deg = [10.0, -20.0, 5.0]\norientation_wxyz = [1.0, 0.0, 0.0, 0.0]",
        ));
        assert!(e.contains("not both"), "{e}");
        let e = err(&VALID.replace("seed = 7", "seed = 7\ncolour = 3"));
        assert!(e.contains("unknown field") && e.contains("line"), "{e}");
        let e = err(&VALID.replace("\"HD\"", "\"8K\""));
        assert!(e.contains("resolution"), "{e}");
        let e = err(&VALID.replace("[90.0, 93.0]", "[90.0, -1.0]"));
        assert!(e.contains("size_mm"), "{e}");
        let e = err(&VALID.replace("[20.0, -10.0, 650.0]", "[20.0, nan, 650.0]"));
        assert!(e.contains("position_mm"), "{e}");
        let e = err(&VALID.replace("coffee.jpg\"\nbox", "nope.jpg\"\nbox"));
        assert!(e.contains("nope.jpg"), "{e}");
        let e = err(&VALID.replace("occluder = 0.2", "occluder = 1.5"));
        assert!(e.contains("occluder"), "{e}");
        let e = err("photo = 3");
        assert!(e.contains("line 1"), "{e}");
        let e = err(&VALID.replace(
            "rotation_deg = [10.0, -20.0, 5.0]",
            "orientation_wxyz = [2.0, 0.0, 0.0, 0.0]",
        ));
        assert!(e.contains("unit quaternion"), "{e}");
    }

    #[test]
    fn build_rejects_card_behind_camera_or_wall() {
        let s = parse(VALID).unwrap();
        let behind = Isometry3::translation(0.0, 0.0, -1000.0);
        let e = s.build(&behind).unwrap_err().to_string();
        assert!(e.contains("test.toml") && e.contains("in front"), "{e}");
        let far = Isometry3::translation(0.0, 0.0, 2000.0);
        let e = s.build(&far).unwrap_err().to_string();
        assert!(e.contains("not behind the card"), "{e}");
        let missing = SceneSpec::load(&scene_path("does-not-exist.toml")).unwrap_err();
        assert!(missing.to_string().contains("does-not-exist.toml"));
    }

    #[test]
    fn truth_has_nonnegative_w() {
        let iso = Isometry3::from_parts(
            Translation3::new(1.0, 2.0, 3.0),
            UnitQuaternion::from_quaternion(Quaternion::new(-0.5, 0.5, 0.5, 0.5)),
        );
        let j = truth_json(&iso, [4.0, 5.0]);
        assert_eq!(j["orientation_wxyz"][0].as_f64(), Some(0.5));
        assert_eq!(j["orientation_wxyz"][1].as_f64(), Some(-0.5));
        assert_eq!(j["frame"], "hand");
        assert_eq!(j["position_mm"][2].as_f64(), Some(3.0));
    }
}
