//! The photo-model (paper §3.1): sampling points on a regular grid of one photo's box.
//! Inner points store their HSV colour; outer points form a strip around the box;
//! `H̄_in` is the mean hue of a central rectangle. Saved as versioned JSON.

use std::path::{Path, PathBuf};

use image::RgbImage;
use serde::{Deserialize, Serialize};

use crate::estimator::settings::ModelSettings;
use crate::vision::color::{circular_mean_hue, is_chromatic, rgb_to_hsv, ColorClasses, BLACK, GRAY, WHITE};

/// File format tag and version written into every model file.
pub const FORMAT: &str = "photopose-model";
/// The model file version this build writes and reads.
pub const VERSION: u32 = 1;

/// A problem building, reading or writing a photo-model.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// The requested box does not lie inside the photo.
    #[error("{path}: box {x},{y},{w},{h} does not lie inside the {width}x{height} photo")]
    BoxOutside {
        /// The photo.
        path: PathBuf,
        /// Left column of the box, photo pixels.
        x: i64,
        /// Top row of the box, photo pixels.
        y: i64,
        /// Box width, pixels.
        w: i64,
        /// Box height, pixels.
        h: i64,
        /// Photo width, pixels.
        width: u32,
        /// Photo height, pixels.
        height: u32,
    },
    /// The box is narrower or lower than 8 pixels.
    #[error("{path}: box {w}x{h} is too small (at least 8x8 pixels)")]
    BoxTooSmall {
        /// The photo.
        path: PathBuf,
        /// Box width, pixels.
        w: i64,
        /// Box height, pixels.
        h: i64,
    },
    /// The model file could not be read.
    #[error("cannot read {path}: {reason}")]
    Read {
        /// The model file.
        path: PathBuf,
        /// The I/O error.
        reason: std::io::Error,
    },
    /// The model file could not be written.
    #[error("cannot write {path}: {reason}")]
    Write {
        /// The model file.
        path: PathBuf,
        /// The I/O error.
        reason: std::io::Error,
    },
    /// The text is not JSON of a photopose model (or the model would not serialise).
    #[error("{path}: not a photopose model: {message}")]
    Parse {
        /// The model file.
        path: PathBuf,
        /// What is wrong, e.g. the JSON parser's message.
        message: String,
    },
    /// The file's format version is not [`VERSION`].
    #[error("{path}: model format version {found} is not supported (this build reads {VERSION})")]
    Version {
        /// The model file.
        path: PathBuf,
        /// The version the file declares (0 when it has none).
        found: u32,
    },
    /// The model parses but its content is unusable.
    #[error("{path}: model has {problem}")]
    Invalid {
        /// The model file.
        path: PathBuf,
        /// What is wrong, e.g. "no inner points".
        problem: String,
    },
}

/// A box in photo pixels, `(x, y)` its top-left corner.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct PixelBox {
    /// Left column.
    pub x: u32,
    /// Top row.
    pub y: u32,
    /// Width, pixels.
    pub w: u32,
    /// Height, pixels.
    pub h: u32,
}

/// An inner sampling point: position relative to the box centre (photo pixels) and colour.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "[f64; 5]", into = "[f64; 5]")]
pub struct InnerPoint {
    /// Photo pixels right of the box centre.
    pub x: f64,
    /// Photo pixels below the box centre.
    pub y: f64,
    /// OpenCV hue, 0–179.
    pub h: u8,
    /// Saturation, 0–255.
    pub s: u8,
    /// Value, 0–255.
    pub v: u8,
}

impl TryFrom<[f64; 5]> for InnerPoint {
    type Error = String;

    /// A point as stored: its colour must be OpenCV HSV (H 0–179, S and V 0–255).
    fn try_from(a: [f64; 5]) -> Result<Self, String> {
        let [x, y, h, s, v] = a;
        let in_range = |c: f64, max: f64| (0.0..=max).contains(&c);
        if !(in_range(h, 179.0) && in_range(s, 255.0) && in_range(v, 255.0)) {
            return Err(format!(
                "inner point ({x}, {y}) has colour [{h}, {s}, {v}] outside H 0–179, S and V 0–255"
            ));
        }
        Ok(Self {
            x,
            y,
            h: h.round() as u8,
            s: s.round() as u8,
            v: v.round() as u8,
        })
    }
}

impl From<InnerPoint> for [f64; 5] {
    fn from(p: InnerPoint) -> Self {
        [p.x, p.y, p.h as f64, p.s as f64, p.v as f64]
    }
}

/// The detection a model's box came from (`photopose model` without `--box`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DetectionRecord {
    /// COCO class name, e.g. "cup".
    pub class: String,
    /// Detector score, 0–1.
    pub score: f64,
    /// The detected box `[x, y, w, h]` in photo pixels, `(x, y)` its top-left corner
    /// (before rounding to the model's integer box).
    #[serde(rename = "box")]
    pub bbox: [f64; 4],
}

/// The photo-model as stored on disk.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PhotoModel {
    /// Always [`FORMAT`].
    pub format: String,
    /// The file format's [`VERSION`].
    pub version: u32,
    /// The source photo as given to `photopose model`.
    pub photo: String,
    /// The box sampled, photo pixels.
    #[serde(rename = "box")]
    pub bbox: PixelBox,
    /// Model frame length `L_P` (along its x axis), pixels.
    pub l_p: f64,
    /// Model frame width `B_P` (along its y axis), pixels.
    pub b_p: f64,
    /// Grid step of the sampling points, pixels.
    pub step_px: f64,
    /// Width of the outer strip, pixels.
    pub outer_width_px: f64,
    /// Mean hue `H̄_in` of the central rectangle (OpenCV units, circular mean).
    pub mean_hue: f64,
    /// Mean saturation of the central rectangle's chromatic points (0 if none).
    pub mean_saturation: f64,
    /// Colour class that dominates the central rectangle: "chromatic", "black", "gray" or "white".
    pub center_class: String,
    /// Inner points `[x, y, H, S, V]`, x right and y down from the box centre.
    pub inner: Vec<InnerPoint>,
    /// Outer strip points `[x, y]` from the box centre.
    pub outer: Vec<[f64; 2]>,
    /// Where the box came from when a detector found it; absent for a `--box` model.
    /// Optional in both directions: readers that predate it ignore it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub detection: Option<DetectionRecord>,
}

impl PhotoModel {
    /// Samples `photo` inside `bbox` (`[x, y, w, h]`, `(x, y)` the top-left corner;
    /// `path` only names the photo in messages and the file): inner points on a grid
    /// with the colour of their cell, the outer strip around the box, and the colour of
    /// the central rectangle.
    pub fn build(
        photo: &RgbImage,
        path: &Path,
        bbox: [i64; 4],
        settings: &ModelSettings,
        classes: &ColorClasses,
    ) -> Result<PhotoModel, ModelError> {
        let pixel_box = check_box(photo, path, bbox)?;
        let (wf, hf) = (pixel_box.w as f64, pixel_box.h as f64);
        let (step, outer_width) = spacing(settings, wf, hf);
        let centre = (pixel_box.x as f64 + wf / 2.0, pixel_box.y as f64 + hf / 2.0);
        let inner = inner_points(photo, centre, (wf, hf), step);
        let outer = outer_points((wf, hf), step, outer_width);
        let half = (wf / 2.0, hf / 2.0);
        let central = (settings.center_fraction * half.0, settings.center_fraction * half.1);
        let (mean_hue, mean_saturation, center_class) = central_colour(&inner, central, classes);
        Ok(PhotoModel {
            format: FORMAT.into(),
            version: VERSION,
            photo: path.display().to_string(),
            bbox: pixel_box,
            l_p: wf,
            b_p: hf,
            step_px: step,
            outer_width_px: outer_width,
            mean_hue,
            mean_saturation,
            center_class: center_class.into(),
            inner,
            outer,
            detection: None,
        })
    }

    /// Reads and checks a model file.
    pub fn load(path: &Path) -> Result<PhotoModel, ModelError> {
        let text = std::fs::read_to_string(path).map_err(|reason| ModelError::Read {
            path: path.to_path_buf(),
            reason,
        })?;
        Self::parse(&text, path)
    }

    /// Parses and checks model file text; `path` only names the file in messages.
    pub fn parse(text: &str, path: &Path) -> Result<PhotoModel, ModelError> {
        let value: serde_json::Value = serde_json::from_str(text).map_err(|e| ModelError::Parse {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        if value.get("format").and_then(|f| f.as_str()) != Some(FORMAT) {
            return Err(ModelError::Parse {
                path: path.to_path_buf(),
                message: format!("missing \"format\": \"{FORMAT}\""),
            });
        }
        let version = value.get("version").and_then(|v| v.as_u64()).unwrap_or(0) as u32;
        if version != VERSION {
            return Err(ModelError::Version {
                path: path.to_path_buf(),
                found: version,
            });
        }
        let model: PhotoModel = serde_json::from_value(value).map_err(|e| ModelError::Parse {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        let invalid = |problem: &str| ModelError::Invalid {
            path: path.to_path_buf(),
            problem: problem.into(),
        };
        if model.inner.is_empty() {
            return Err(invalid("no inner points"));
        }
        if !(model.l_p > 0.0 && model.b_p > 0.0 && model.l_p.is_finite() && model.b_p.is_finite()) {
            return Err(invalid("a non-positive box size L_P × B_P"));
        }
        let finite = model.inner.iter().all(|p| p.x.is_finite() && p.y.is_finite())
            && model.outer.iter().all(|p| p[0].is_finite() && p[1].is_finite())
            && [
                model.mean_hue,
                model.mean_saturation,
                model.step_px,
                model.outer_width_px,
            ]
            .iter()
            .all(|v| v.is_finite() && *v >= 0.0);
        if !finite {
            return Err(invalid(
                "a non-finite number, or a negative hue, saturation, step or strip width",
            ));
        }
        Ok(model)
    }

    /// Writes the model as JSON.
    pub fn save(&self, path: &Path) -> Result<(), ModelError> {
        let text = serde_json::to_string(self).map_err(|e| ModelError::Parse {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        std::fs::write(path, text).map_err(|reason| ModelError::Write {
            path: path.to_path_buf(),
            reason,
        })
    }

    /// The colour code the mean colour of the central rectangle has: its hue when
    /// chromatic, else the achromatic class code.
    pub fn center_code(&self) -> u8 {
        match self.center_class.as_str() {
            "black" => BLACK,
            "gray" => GRAY,
            "white" => WHITE,
            _ => self.mean_hue.round() as u8 % 180,
        }
    }
}

/// The box `[x, y, w, h]` if it lies inside `photo` and is at least 8 × 8 pixels.
fn check_box(photo: &RgbImage, path: &Path, [x, y, w, h]: [i64; 4]) -> Result<PixelBox, ModelError> {
    let (pw, ph) = photo.dimensions();
    if x < 0 || y < 0 || w <= 0 || h <= 0 || x + w > pw as i64 || y + h > ph as i64 {
        return Err(ModelError::BoxOutside {
            path: path.to_path_buf(),
            x,
            y,
            w,
            h,
            width: pw,
            height: ph,
        });
    }
    if w < 8 || h < 8 {
        return Err(ModelError::BoxTooSmall {
            path: path.to_path_buf(),
            w,
            h,
        });
    }
    Ok(PixelBox {
        x: x as u32,
        y: y as u32,
        w: w as u32,
        h: h as u32,
    })
}

/// The grid step and the outer strip's width (photo pixels) for a `w` × `h` box: as
/// configured, or a step that puts about `target_points` points in the box and a strip
/// 15 % of its shorter side wide.
fn spacing(settings: &ModelSettings, w: f64, h: f64) -> (f64, f64) {
    let step = if settings.step_px > 0.0 {
        settings.step_px
    } else {
        (w * h / settings.target_points as f64).sqrt().max(1.0)
    };
    let outer_width = if settings.outer_width_px > 0.0 {
        settings.outer_width_px
    } else {
        0.15 * w.min(h)
    };
    (step, outer_width)
}

/// Grid positions every `step` along a side of length `len`, centred on 0.
fn grid(len: f64, step: f64) -> Vec<f64> {
    let n = (len / step).floor().max(1.0) as usize;
    let start = -(n as f64 - 1.0) * step / 2.0;
    (0..n).map(|i| start + i as f64 * step).collect()
}

/// The inner points of a `size` box centred on `centre` (photo pixels), row by row, each
/// with the HSV of its grid cell's mean colour.
fn inner_points(photo: &RgbImage, (cx, cy): (f64, f64), (w, h): (f64, f64), step: f64) -> Vec<InnerPoint> {
    let mut inner = Vec::new();
    for &py in &grid(h, step) {
        for &px in &grid(w, step) {
            let (r, g, b) = mean_rgb(photo, cx + px, cy + py, step);
            let (hh, s, v) = rgb_to_hsv(r, g, b);
            inner.push(InnerPoint {
                x: px,
                y: py,
                h: hh,
                s,
                v,
            });
        }
    }
    inner
}

/// The outer strip of a `w` × `h` box: the grid continued beyond the box, up to
/// `outer_width` away.
fn outer_points((w, h): (f64, f64), step: f64, outer_width: f64) -> Vec<[f64; 2]> {
    let (half_w, half_h) = (w / 2.0, h / 2.0);
    let reach_x = ((half_w + outer_width) / step).floor() as i64;
    let reach_y = ((half_h + outer_width) / step).floor() as i64;
    let mut outer = Vec::new();
    for j in -reach_y..=reach_y {
        for i in -reach_x..=reach_x {
            let (px, py) = (i as f64 * step, j as f64 * step);
            let dx = px.abs() - half_w;
            let dy = py.abs() - half_h;
            let outside = dx > step * 0.5 || dy > step * 0.5;
            if outside && dx <= outer_width && dy <= outer_width {
                outer.push([px, py]);
            }
        }
    }
    outer
}

/// `H̄_in`, the mean saturation of the chromatic points and the dominant class of the
/// inner points within `(fx, fy)` of the centre (the central rectangle).
fn central_colour(inner: &[InnerPoint], (fx, fy): (f64, f64), classes: &ColorClasses) -> (f64, f64, &'static str) {
    let central: Vec<&InnerPoint> = inner.iter().filter(|p| p.x.abs() <= fx && p.y.abs() <= fy).collect();
    let center: Vec<u8> = central.iter().map(|p| classes.code(p.h, p.s, p.v)).collect();
    let chromatic_sat: Vec<f64> = central
        .iter()
        .filter(|p| is_chromatic(classes.code(p.h, p.s, p.v)))
        .map(|p| p.s as f64)
        .collect();
    let mean_saturation = chromatic_sat.iter().sum::<f64>() / (chromatic_sat.len().max(1) as f64);
    let (mean_hue, center_class) = center_colour(&center);
    (mean_hue, mean_saturation, center_class)
}

/// Mean RGB of the grid cell (`step` × `step` pixels, at least 3 × 3) centred on a photo
/// position, clamped to the photo: the colour the camera sees there once the photo is
/// shrunk to a few pixels per sample.
fn mean_rgb(photo: &RgbImage, x: f64, y: f64, step: f64) -> (u8, u8, u8) {
    let (w, h) = photo.dimensions();
    let r = (step / 2.0).floor().max(1.0) as i64;
    let (xi, yi) = (x.floor() as i64, y.floor() as i64);
    let mut acc = [0u64; 3];
    let mut n = 0u64;
    for dy in -r..=r {
        for dx in -r..=r {
            let px = (xi + dx).clamp(0, w as i64 - 1) as u32;
            let py = (yi + dy).clamp(0, h as i64 - 1) as u32;
            let p = photo.get_pixel(px, py).0;
            for c in 0..3 {
                acc[c] += p[c] as u64;
            }
            n += 1;
        }
    }
    ((acc[0] / n) as u8, (acc[1] / n) as u8, (acc[2] / n) as u8)
}

/// `H̄_in` and the dominant class of the central rectangle's colour codes.
fn center_colour(codes: &[u8]) -> (f64, &'static str) {
    let chromatic: Vec<u8> = codes.iter().copied().filter(|&c| is_chromatic(c)).collect();
    let count = |k: u8| codes.iter().filter(|&&c| c == k).count();
    let achromatic = [(count(BLACK), "black"), (count(GRAY), "gray"), (count(WHITE), "white")];
    let (best_n, best_name) = achromatic.iter().copied().max_by_key(|a| a.0).unwrap_or((0, "gray"));
    let mean = circular_mean_hue(chromatic.iter().copied()).unwrap_or(0.0);
    if chromatic.len() >= best_n {
        (mean, "chromatic")
    } else {
        (mean, best_name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::Rgb;

    fn settings(step: f64) -> ModelSettings {
        ModelSettings {
            step_px: step,
            outer_width_px: 10.0,
            ..ModelSettings::default()
        }
    }

    #[test]
    fn grid_covers_box_and_strip_surrounds_it() {
        let mut photo = RgbImage::from_pixel(100, 80, Rgb([20, 200, 20]));
        for y in 20..60 {
            for x in 30..70 {
                photo.put_pixel(x, y, Rgb([220, 30, 30]));
            }
        }
        let m = PhotoModel::build(
            &photo,
            Path::new("p.png"),
            [30, 20, 40, 40],
            &settings(5.0),
            &ColorClasses::default(),
        )
        .unwrap();
        assert_eq!(m.inner.len(), 64);
        assert_eq!((m.l_p, m.b_p), (40.0, 40.0));
        // Points are centred on the box: from −17.5 to 17.5.
        assert!(m.inner.iter().all(|p| p.x.abs() <= 17.5 && p.y.abs() <= 17.5));
        assert!(m.inner.iter().all(|p| p.h == 0 && p.s > 200));
        assert_eq!(m.center_class, "chromatic");
        assert!(m.mean_hue < 1.0 || m.mean_hue > 179.0);
        assert!(!m.outer.is_empty());
        for p in &m.outer {
            let out = p[0].abs() > 20.0 || p[1].abs() > 20.0;
            let near = p[0].abs() <= 30.0 && p[1].abs() <= 30.0;
            assert!(out && near, "{p:?}");
        }
    }

    #[test]
    fn box_outside_photo_is_an_error_naming_the_photo() {
        let photo = RgbImage::new(50, 50);
        let e = PhotoModel::build(
            &photo,
            Path::new("pear.jpg"),
            [30, 30, 40, 10],
            &settings(4.0),
            &ColorClasses::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("pear.jpg") && e.contains("does not lie inside the 50x50 photo"),
            "{e}"
        );
    }

    #[test]
    fn save_and_load_round_trip_and_reject_bad_files() {
        let photo = RgbImage::from_pixel(64, 64, Rgb([128, 128, 128]));
        let m = PhotoModel::build(
            &photo,
            Path::new("g.png"),
            [8, 8, 48, 40],
            &settings(4.0),
            &ColorClasses::default(),
        )
        .unwrap();
        assert_eq!(m.center_class, "gray");
        let dir = std::env::temp_dir().join(format!("photopose-model-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("g.model");
        m.save(&path).unwrap();
        assert_eq!(PhotoModel::load(&path).unwrap(), m);
        let bad = dir.join("bad.model");
        std::fs::write(&bad, "{\"format\": \"photopose-model\", \"version\": 7}").unwrap();
        let e = PhotoModel::load(&bad).unwrap_err().to_string();
        assert!(e.contains("bad.model") && e.contains("version 7"), "{e}");
        std::fs::write(&bad, "not json").unwrap();
        let e = PhotoModel::load(&bad).unwrap_err().to_string();
        assert!(e.contains("bad.model") && e.contains("not a photopose model"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn detection_is_optional_in_the_file() {
        let photo = RgbImage::from_pixel(64, 64, Rgb([200, 40, 40]));
        let mut m = PhotoModel::build(
            &photo,
            Path::new("r.png"),
            [8, 8, 48, 40],
            &settings(4.0),
            &ColorClasses::default(),
        )
        .unwrap();
        let plain = serde_json::to_value(&m).unwrap();
        assert!(plain.get("detection").is_none(), "absent for a --box model");
        m.detection = Some(DetectionRecord {
            class: "cup".into(),
            score: 0.59,
            bbox: [7.6, 8.2, 48.1, 39.9],
        });
        let text = serde_json::to_string(&m).unwrap();
        let value: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(
            value["detection"],
            serde_json::json!({"class": "cup", "score": 0.59, "box": [7.6, 8.2, 48.1, 39.9]})
        );
        assert_eq!(value["version"], 1);
        let dir = std::env::temp_dir().join(format!("photopose-detection-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("d.model");
        std::fs::write(&path, &text).unwrap();
        assert_eq!(PhotoModel::load(&path).unwrap(), m);
        // A file without the field (written before it existed) still loads.
        let mut old = value.clone();
        old.as_object_mut().unwrap().remove("detection");
        std::fs::write(&path, old.to_string()).unwrap();
        assert_eq!(PhotoModel::load(&path).unwrap().detection, None);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
