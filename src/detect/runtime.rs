//! The YOLO network run by ONNX Runtime through `ort` (cargo feature `detect`). The
//! runtime is a shared library loaded when the first detector is made: from
//! `ORT_DYLIB_PATH` when set, else from `[detect] onnxruntime`.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use image::RgbImage;
use ort::environment::Environment;
use ort::session::Session;
use ort::value::{TensorRef, ValueType};

use super::letterbox::Letterbox;
use super::{coco, decode, postprocess, DetectError, Detections};
use crate::detect::settings::DetectSettings;

/// ONNX Runtime allows one environment per process; every detector shares it.
static ENVIRONMENT: Mutex<Option<Environment>> = Mutex::new(None);

/// The ONNX Runtime library to load and where that choice came from.
pub fn library_path(settings: &DetectSettings) -> (PathBuf, &'static str) {
    match std::env::var_os("ORT_DYLIB_PATH") {
        Some(p) if !p.is_empty() => (PathBuf::from(p), "ORT_DYLIB_PATH"),
        _ => (settings.onnxruntime.clone(), "[detect] onnxruntime"),
    }
}

/// A YOLO network ready to run on photos.
pub struct Detector {
    session: Session,
    model: PathBuf,
    input_name: String,
    input_w: u32,
    input_h: u32,
    iou_threshold: f32,
    /// The letterboxed input, reused from photo to photo.
    tensor: Vec<f32>,
}

impl Detector {
    /// Loads ONNX Runtime (once per process) and the network of `settings.model`.
    pub fn new(settings: &DetectSettings) -> Result<Self, DetectError> {
        let (library, origin) = library_path(settings);
        if !library.is_file() {
            return Err(DetectError::LibraryMissing { path: library, origin });
        }
        if !settings.model.is_file() {
            return Err(DetectError::ModelMissing {
                path: settings.model.clone(),
            });
        }
        let environment = environment(&library)?;
        let model = settings.model.clone();
        let threads = settings.threads;
        let session = guarded(&model, || {
            let mut builder = Session::builder(&environment).map_err(|e| e.to_string())?;
            if threads > 0 {
                builder = builder.with_intra_threads(threads).map_err(|e| e.to_string())?;
            }
            builder.commit_from_file(&model).map_err(|e| e.to_string())
        })?;
        let input = session.inputs().first().ok_or_else(|| DetectError::UnsupportedInput {
            model: model.clone(),
            shape: Vec::new(),
        })?;
        let shape: Vec<i64> = match input.dtype() {
            ValueType::Tensor { shape, .. } => shape.iter().copied().collect(),
            _ => Vec::new(),
        };
        let unsupported = || DetectError::UnsupportedInput {
            model: model.clone(),
            shape: shape.clone(),
        };
        if shape.len() != 4 || !(shape[0] == 1 || shape[0] < 0) || !(shape[1] == 3 || shape[1] < 0) {
            return Err(unsupported());
        }
        let side = |d: i64| if d > 0 { d as u32 } else { settings.input_size };
        let (input_h, input_w) = (side(shape[2]), side(shape[3]));
        tracing::debug!("detector {}: input {:?} → {input_w}×{input_h}", model.display(), shape);
        Ok(Self {
            input_name: input.name().to_string(),
            session,
            model,
            input_w,
            input_h,
            iou_threshold: settings.iou_threshold,
            tensor: Vec::new(),
        })
    }

    /// The network's input size, width × height.
    pub fn input_size(&self) -> (u32, u32) {
        (self.input_w, self.input_h)
    }

    /// Detects objects in `photo`: every box of every class scoring at least `min_score`
    /// after NMS, best first, in photo pixels.
    pub fn detect(&mut self, photo: &RgbImage, min_score: f32) -> Result<Detections, DetectError> {
        let start = std::time::Instant::now();
        let (pw, ph) = photo.dimensions();
        let letterbox = Letterbox::new(pw, ph, self.input_w, self.input_h);
        letterbox.fill(photo, &mut self.tensor);
        let prepared = start.elapsed();
        let shape = [1usize, 3, self.input_h as usize, self.input_w as usize];
        let (model, name, tensor) = (&self.model, self.input_name.as_str(), &self.tensor);
        let session = &mut self.session;
        let outputs = guarded(model, || {
            let input = TensorRef::from_array_view((shape, tensor.as_slice())).map_err(|e| e.to_string())?;
            let outputs = session.run(ort::inputs![name => input]).map_err(|e| e.to_string())?;
            // Every f32 output as (shape, data); the first with a YOLO layout is used.
            let mut all = Vec::new();
            for (_, value) in outputs.iter() {
                if let Ok((shape, data)) = value.try_extract_tensor::<f32>() {
                    let dims: Vec<usize> = shape.iter().map(|&d| d.max(0) as usize).collect();
                    all.push((dims, data.to_vec()));
                }
            }
            Ok(all)
        })?;
        let ran = start.elapsed();
        let classes = coco::NAMES.len();
        let chosen = outputs
            .iter()
            .find(|(dims, _)| decode::Layout::from_shape(dims, classes).is_some())
            .or_else(|| outputs.first());
        let Some((dims, data)) = chosen else {
            return Err(DetectError::Runtime {
                path: self.model.clone(),
                message: "the network has no float tensor output".into(),
            });
        };
        let detections =
            postprocess(data, dims, &letterbox, min_score, self.iou_threshold).map_err(|e| DetectError::InModel {
                model: self.model.clone(),
                problem: Box::new(e),
            })?;
        tracing::debug!(
            "detection: letterbox {:.1} ms, network {:.1} ms, decoding and NMS {:.1} ms",
            prepared.as_secs_f64() * 1e3,
            (ran - prepared).as_secs_f64() * 1e3,
            (start.elapsed() - ran).as_secs_f64() * 1e3
        );
        Ok(detections)
    }
}

/// The process's ONNX Runtime environment, loading `library` the first time.
fn environment(library: &Path) -> Result<Environment, DetectError> {
    let mut slot = ENVIRONMENT.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    if let Some(env) = slot.as_ref() {
        return Ok(env.clone());
    }
    let env = guarded(library, || {
        ort::init_from(library)
            .map_err(|e| match &e {
                // The loader's own reason (e.g. "invalid ELF header") is in the error's sources.
                ort::LoadDynamicError::Dlopen { error, .. } => {
                    format!("cannot load it as ONNX Runtime: {}", chain(error))
                }
                _ => e.to_string(),
            })?
            .with_name("photopose")
            .build()
            .map_err(|e| e.to_string())
    })?;
    *slot = Some(env.clone());
    Ok(env)
}

/// An error and its sources, joined by ": ".
fn chain(error: &dyn std::error::Error) -> String {
    let mut text = error.to_string();
    let mut source = error.source();
    while let Some(e) = source {
        text = format!("{text}: {e}");
        source = e.source();
    }
    text
}

/// Runs `f`, turning its error message, or a panic inside `ort`, into an error naming `path`.
fn guarded<T>(path: &Path, f: impl FnOnce() -> Result<T, String>) -> Result<T, DetectError> {
    let runtime_error = |message: String| DetectError::Runtime {
        path: path.to_path_buf(),
        message: message.replace('\n', " "),
    };
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(result) => result.map_err(runtime_error),
        Err(panic) => {
            let message = panic
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "ONNX Runtime failed".into());
            Err(runtime_error(message))
        }
    }
}
