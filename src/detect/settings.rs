//! `[detect]`: the YOLO detector of `photopose model` — network, ONNX Runtime library,
//! score and overlap thresholds — as written (serde, every field defaulted, unknown keys
//! rejected) and validated, with its paths resolved ([`DetectSettings`]).

use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::config::InvalidSetting;

/// `[detect]` as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub(crate) struct RawDetect {
    model: PathBuf,
    onnxruntime: PathBuf,
    min_score: f32,
    iou_threshold: f32,
    input_size: u32,
    threads: usize,
}

impl Default for RawDetect {
    fn default() -> Self {
        Self {
            model: PathBuf::from("../.detect/yolov3-tiny.onnx"),
            onnxruntime: PathBuf::from("../.detect/onnxruntime/libonnxruntime.so.1.31.1"),
            min_score: 0.25,
            iou_threshold: 0.45,
            input_size: 640,
            threads: 0,
        }
    }
}

impl RawDetect {
    /// The validated settings, relative paths resolved against `dir` (the configuration
    /// file's directory), or the first field that is wrong.
    pub(crate) fn validate(self, dir: &Path) -> Result<DetectSettings, InvalidSetting> {
        let invalid = |field, problem| InvalidSetting::new("detect", field, problem);
        for (field, v) in [("min_score", self.min_score), ("iou_threshold", self.iou_threshold)] {
            if !(v > 0.0 && v <= 1.0) {
                return Err(invalid(field, format!("{v} must lie in (0, 1]")));
            }
        }
        if self.input_size < 32 || !self.input_size.is_multiple_of(32) {
            return Err(invalid(
                "input_size",
                format!("{} must be a positive multiple of 32", self.input_size),
            ));
        }
        Ok(DetectSettings {
            model: dir.join(self.model),
            onnxruntime: dir.join(self.onnxruntime),
            min_score: self.min_score,
            iou_threshold: self.iou_threshold,
            input_size: self.input_size,
            threads: self.threads,
        })
    }
}

/// `[detect]`: the YOLO detector of `photopose model` (cargo feature `detect`).
#[derive(Debug, Clone, PartialEq)]
pub struct DetectSettings {
    /// The YOLO network (.onnx), resolved against the configuration file's directory.
    pub model: PathBuf,
    /// The ONNX Runtime shared library (≥ 1.31), resolved likewise; `ORT_DYLIB_PATH`
    /// overrides it.
    pub onnxruntime: PathBuf,
    /// Detections scoring below this (0–1) are dropped.
    pub min_score: f32,
    /// Per-class NMS: of two boxes overlapping by more than this IoU the weaker goes.
    pub iou_threshold: f32,
    /// Input side for networks whose input size is not fixed (a multiple of 32).
    pub input_size: u32,
    /// ONNX Runtime intra-op threads, 0 = its default (one per core).
    pub threads: usize,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_resolve_against_the_directory() {
        let d = RawDetect::default().validate(Path::new("/etc/photopose")).unwrap();
        assert_eq!(d.model, Path::new("/etc/photopose/../.detect/yolov3-tiny.onnx"));
        let raw = RawDetect {
            onnxruntime: PathBuf::from("/opt/ort/libonnxruntime.so"),
            ..RawDetect::default()
        };
        let d = raw.validate(Path::new("/etc")).unwrap();
        assert_eq!(d.onnxruntime, Path::new("/opt/ort/libonnxruntime.so"));
    }

    #[test]
    fn input_size_must_be_a_multiple_of_32() {
        let raw = RawDetect {
            input_size: 100,
            ..RawDetect::default()
        };
        let e = raw.validate(Path::new(".")).unwrap_err().to_string();
        assert_eq!(e, "[detect] input_size: 100 must be a positive multiple of 32");
    }
}
