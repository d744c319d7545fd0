//! Object detection for building a photo-model (paper §3.1: "a detector gives the model
//! frame"): a COCO-trained YOLO network run through ONNX Runtime finds the object's box
//! in the photo.
//!
//! The pipeline, photo → boxes in photo pixels:
//! [`letterbox`] (aspect-preserving resize onto gray 114) → the network (`Detector`,
//! cargo feature `detect`) → [`decode`] (YOLOv8/YOLO11 `[1, 84, N]` or YOLOv5 `[1, N, 85]`
//! outputs, recognised from the shape) → [`nms`] per class → back to photo pixels
//! ([`postprocess`]) → [`choose`] the requested class or the best detection. Everything
//! but the ONNX Runtime session is plain Rust and builds without the feature.

pub mod coco;
pub mod decode;
pub mod letterbox;
pub mod nms;
#[cfg(feature = "detect")]
mod runtime;
pub mod settings;

use std::path::{Path, PathBuf};

#[cfg(feature = "detect")]
pub use runtime::{library_path, Detector};

use letterbox::Letterbox;

/// A problem detecting the object in a photo.
#[derive(Debug, thiserror::Error)]
pub enum DetectError {
    /// The requested class name is not one of the COCO classes.
    #[error("{name:?} is not a COCO class{}; the 80 COCO classes are: {}", did_you_mean(.suggestion), coco::NAMES.join(", "))]
    UnknownClass {
        /// The name as given.
        name: String,
        /// The COCO name closest to it, when it looks like a typo.
        suggestion: Option<&'static str>,
    },
    /// No box of the requested class reached the minimum score.
    #[error("{photo}: no {class} detected (best {class} score {best:.3}, below the minimum score {min_score})")]
    NotDetected {
        /// The photo searched.
        photo: PathBuf,
        /// COCO name of the requested class.
        class: String,
        /// Best score the class reached anywhere in the photo, 0–1.
        best: f32,
        /// Score a detection needs, 0–1.
        min_score: f32,
    },
    /// No box of any class reached the minimum score.
    #[error(
        "{photo}: nothing detected (best: {best_class} with score {best:.3}, below the minimum score {min_score})"
    )]
    NothingDetected {
        /// The photo searched.
        photo: PathBuf,
        /// COCO name of the class that scored highest.
        best_class: String,
        /// That class's best score, 0–1.
        best: f32,
        /// Score a detection needs, 0–1.
        min_score: f32,
    },
    /// A network output's shape is neither the YOLOv8/YOLO11 nor the YOLOv5 layout.
    #[error(
        "output shape {shape:?} is not a YOLO layout photopose reads: expected [1, {}, N] (YOLOv8/YOLO11) or [1, N, {}] (YOLOv5, the converted YOLOv3-tiny)",
        4 + classes,
        5 + classes
    )]
    UnsupportedOutput {
        /// The output's shape.
        shape: Vec<usize>,
        /// Number of classes the network was expected to score.
        classes: usize,
    },
    /// A network output holds a different number of values than its shape implies.
    #[error("output of shape {shape:?} holds {len} values")]
    OutputLength {
        /// The output's shape.
        shape: Vec<usize>,
        /// Number of values it holds.
        len: usize,
    },
    /// The network has no input, or its first input is not one RGB image `[1, 3, H, W]`.
    #[error("{model}: input shape {shape:?} is not one RGB image [1, 3, H, W]")]
    UnsupportedInput {
        /// The network file.
        model: PathBuf,
        /// The input's shape, negative for a free dimension (empty when there is no tensor input).
        shape: Vec<i64>,
    },
    /// The network's output could not be turned into detections.
    #[error("{model}: {problem}")]
    InModel {
        /// The network file.
        model: PathBuf,
        /// What was wrong with the output.
        problem: Box<DetectError>,
    },
    /// The ONNX Runtime shared library path is not a file.
    #[error("ONNX Runtime library {path} (from {origin}) not found or not a file: run tools/setup-detect, or point ORT_DYLIB_PATH or [detect] onnxruntime at libonnxruntime.so 1.31 or newer")]
    LibraryMissing {
        /// The library path tried.
        path: PathBuf,
        /// Where the path came from: `ORT_DYLIB_PATH` or `[detect] onnxruntime`.
        origin: &'static str,
    },
    /// The `[detect] model` path is not a file.
    #[error("detector model {path} not found: run tools/setup-detect, or set [detect] model to a YOLO .onnx file")]
    ModelMissing {
        /// The model path tried.
        path: PathBuf,
    },
    /// ONNX Runtime failed or panicked loading its library, loading the network or running
    /// it, or the network has no float output.
    #[error("{path}: {message}")]
    Runtime {
        /// The library or network file concerned.
        path: PathBuf,
        /// ONNX Runtime's message, on one line.
        message: String,
    },
}

fn did_you_mean(suggestion: &Option<&'static str>) -> String {
    suggestion.map_or_else(String::new, |s| format!(" (did you mean {s:?}?)"))
}

/// An axis-aligned box by its corners, pixels (`x0, y0` top-left, `x1, y1` bottom-right).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rect {
    /// Left edge, pixels.
    pub x0: f32,
    /// Top edge, pixels.
    pub y0: f32,
    /// Right edge, pixels.
    pub x1: f32,
    /// Bottom edge, pixels.
    pub y1: f32,
}

impl Rect {
    /// The box of centre `(cx, cy)` and size `w × h`.
    pub fn from_center(cx: f32, cy: f32, w: f32, h: f32) -> Rect {
        Rect {
            x0: cx - w / 2.0,
            y0: cy - h / 2.0,
            x1: cx + w / 2.0,
            y1: cy + h / 2.0,
        }
    }

    /// Width, pixels (0 when `x1 < x0`).
    pub fn width(&self) -> f32 {
        (self.x1 - self.x0).max(0.0)
    }

    /// Height, pixels (0 when `y1 < y0`).
    pub fn height(&self) -> f32 {
        (self.y1 - self.y0).max(0.0)
    }

    /// Area, square pixels (0 for an empty box).
    pub fn area(&self) -> f32 {
        self.width() * self.height()
    }

    /// Intersection over union (0 when either box is empty).
    pub fn iou(&self, other: &Rect) -> f32 {
        let inter = Rect {
            x0: self.x0.max(other.x0),
            y0: self.y0.max(other.y0),
            x1: self.x1.min(other.x1),
            y1: self.y1.min(other.y1),
        }
        .area();
        let union = self.area() + other.area() - inter;
        if union > 0.0 {
            inter / union
        } else {
            0.0
        }
    }

    /// `[x, y, w, h]` with `(x, y)` the top-left corner.
    pub fn xywh(&self) -> [f32; 4] {
        [self.x0, self.y0, self.width(), self.height()]
    }

    /// The integer box `[x, y, w, h]` of a photo `width × height` this box covers: corners
    /// rounded to the nearest pixel edge and clipped to the photo.
    pub fn pixel_box(&self, width: u32, height: u32) -> [i64; 4] {
        let edge = |v: f32, max: u32| (v.round() as i64).clamp(0, max as i64);
        let (x0, y0) = (edge(self.x0, width), edge(self.y0, height));
        let (x1, y1) = (edge(self.x1, width), edge(self.y1, height));
        [x0, y0, x1 - x0, y1 - y0]
    }
}

/// One detected object: its class, score (0–1) and box. The box is in network-input
/// pixels straight out of [`decode`], in photo pixels after [`postprocess`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Detection {
    /// COCO class id, an index into [`coco::NAMES`].
    pub class: usize,
    /// Confidence, 0–1 (class score, times objectness for YOLOv5 outputs).
    pub score: f32,
    /// The box, in input or photo pixels (see above).
    pub rect: Rect,
}

impl Detection {
    /// The class's COCO name.
    pub fn class_name(&self) -> String {
        coco::name(self.class)
    }
}

/// Everything found in one photo.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Detections {
    /// Detections after NMS, best first, boxes in photo pixels.
    pub list: Vec<Detection>,
    /// The best score each class reached anywhere in the photo, below the minimum too.
    pub best_score: Vec<f32>,
}

/// Turns one network output into detections in photo pixels: decode, per-class NMS,
/// undo the letterbox.
pub fn postprocess(
    data: &[f32],
    shape: &[usize],
    letterbox: &Letterbox,
    min_score: f32,
    iou_threshold: f32,
) -> Result<Detections, DetectError> {
    let decoded = decode::decode(data, shape, coco::NAMES.len(), min_score)?;
    let list = nms::nms(decoded.candidates, iou_threshold)
        .into_iter()
        .map(|d| Detection {
            rect: letterbox.to_photo(&d.rect),
            ..d
        })
        .filter(|d| d.rect.area() > 0.0)
        .collect();
    Ok(Detections {
        list,
        best_score: decoded.best_score,
    })
}

/// The detection of `class` with the highest score, or the best detection of any class
/// when `class` is `None`. `photo` and `min_score` only word the error.
pub fn choose(
    detections: &Detections,
    class: Option<usize>,
    photo: &Path,
    min_score: f32,
) -> Result<Detection, DetectError> {
    let best_of = |c: usize| detections.best_score.get(c).copied().unwrap_or(0.0);
    match class {
        Some(c) => detections
            .list
            .iter()
            .find(|d| d.class == c)
            .copied()
            .ok_or_else(|| DetectError::NotDetected {
                photo: photo.to_path_buf(),
                class: coco::name(c),
                best: best_of(c),
                min_score,
            }),
        None => detections.list.first().copied().ok_or_else(|| {
            let best_class = (0..detections.best_score.len())
                .max_by(|&a, &b| best_of(a).total_cmp(&best_of(b)))
                .unwrap_or(0);
            DetectError::NothingDetected {
                photo: photo.to_path_buf(),
                best_class: coco::name(best_class),
                best: best_of(best_class),
                min_score,
            }
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A YOLOv5-layout output for a 416 × 416 input holding two overlapping cups, a
    /// bowl and a faint dog, as a letterboxed 600 × 400 photo would give.
    fn output() -> (Vec<f32>, Vec<usize>) {
        let rows = [
            // cx, cy, w, h in input pixels, objectness, (class, probability)
            (200.0, 180.0, 190.0, 200.0, 0.9, 41, 0.7),
            (203.0, 182.0, 186.0, 196.0, 0.8, 41, 0.6),
            (350.0, 300.0, 60.0, 40.0, 0.6, 45, 0.9),
            (50.0, 100.0, 30.0, 30.0, 0.3, 16, 0.4),
        ];
        let mut t = Vec::new();
        for (cx, cy, w, h, obj, class, p) in rows {
            let mut row = vec![0.0f32; 85];
            row[..5].copy_from_slice(&[cx, cy, w, h, obj]);
            row[5 + class] = p;
            t.extend(row);
        }
        (t, vec![1, rows.len(), 85])
    }

    #[test]
    fn postprocess_maps_back_to_the_photo_and_choose_picks() {
        let (t, shape) = output();
        let lb = Letterbox::new(600, 400, 416, 416);
        let d = postprocess(&t, &shape, &lb, 0.25, 0.45).unwrap();
        let got: Vec<(String, f32)> = d.list.iter().map(|d| (d.class_name(), d.score)).collect();
        assert_eq!(
            got,
            vec![("cup".to_string(), 0.9 * 0.7), ("bowl".to_string(), 0.6 * 0.9)]
        );
        // The first cup: input x 105..295, y 80..280 → photo (x / s, (y − 69) / s), s = 416/600.
        let s = 416.0 / 600.0;
        let r = d.list[0].rect;
        for (got, want) in [
            (r.x0, 105.0 / s),
            (r.y0, (80.0 - 69.0) / (277.0 / 400.0)),
            (r.x1, 295.0 / s),
            (r.y1, (280.0 - 69.0) / (277.0 / 400.0)),
        ] {
            assert!((got - want).abs() < 1e-3, "{r:?}");
        }
        let photo = Path::new("coffee.jpg");
        assert_eq!(choose(&d, None, photo, 0.25).unwrap().class, 41);
        assert_eq!(choose(&d, Some(45), photo, 0.25).unwrap().class, 45);
        let e = choose(&d, Some(16), photo, 0.25).unwrap_err().to_string();
        assert_eq!(
            e,
            "coffee.jpg: no dog detected (best dog score 0.120, below the minimum score 0.25)"
        );
        let none = postprocess(&t, &shape, &lb, 0.9, 0.45).unwrap();
        let e = choose(&none, None, photo, 0.9).unwrap_err().to_string();
        assert!(
            e.contains("coffee.jpg: nothing detected (best: cup with score 0.630"),
            "{e}"
        );
    }

    #[test]
    fn pixel_box_rounds_and_clips() {
        let r = Rect {
            x0: 148.6,
            y0: -3.0,
            x1: 427.4,
            y1: 401.0,
        };
        assert_eq!(r.pixel_box(600, 400), [149, 0, 278, 400]);
        assert_eq!(r.xywh(), [148.6, -3.0, 427.4 - 148.6, 404.0]);
    }
}
