//! Property tests: random and mutated input to every parser (calibration, configuration,
//! photo-model, images, scene files, replay frame lists) and to the validation of shared-memory frames never panics, every
//! error is one line naming the file, and whatever is accepted is safe to use.

use std::path::Path;

use photopose::camera::calibration::{Calibration, Resolution};
use photopose::capture::sequence::FrameRecord;
use photopose::config::{Config, DEFAULT_TOML, EXAMPLE_CALIBRATION};
use photopose::estimator::model::PhotoModel;
use photopose::render::SceneSpec;
use photopose::transport::messages::{validate_frame, FrameFault, FrameHeader};
use photopose::vision::frame::StereoImages;
use photopose::vision::lookup::SbsBytes;
use photopose::vision::PixelFormat;
use proptest::prelude::*;

use crate::common::{data, repo};

/// Fragments that break parsers in interesting ways: separators, non-numbers, signs,
/// brackets, line ends, huge exponents.
const SNIPPETS: [&str; 16] = [
    ",", "nan", "inf", "-", "0", "=", "[", "]", "\n", "1e999", "\"", "#", ".", " ", "NaN", "-0",
];

/// `text` after a few random edits: a byte replaced, deleted, a snippet inserted, or the
/// text cut short.
fn mutated(text: String) -> impl Strategy<Value = String> {
    let len = text.len().max(1);
    prop::collection::vec((0..len, any::<u8>(), 0..SNIPPETS.len(), 0u8..4), 1..6).prop_map(move |edits| {
        let mut b = text.clone().into_bytes();
        for (at, byte, snippet, op) in edits {
            let at = at.min(b.len());
            match op {
                0 if at < b.len() => b[at] = byte,
                1 if at < b.len() => {
                    b.remove(at);
                }
                2 => {
                    b.splice(at..at, SNIPPETS[snippet].bytes());
                }
                _ => b.truncate(at),
            }
        }
        String::from_utf8_lossy(&b).into_owned()
    })
}

/// Random text or a mutation of `valid`.
fn inputs(valid: String) -> impl Strategy<Value = String> {
    prop_oneof![1 => any::<String>(), 4 => mutated(valid)]
}

/// The example model cut down to a few points (the real file is 138 kB).
fn small_model() -> String {
    let text = std::fs::read_to_string(data("examples/rocket.model")).expect("model");
    let mut v: serde_json::Value = serde_json::from_str(&text).expect("json");
    for key in ["inner", "outer"] {
        v[key].as_array_mut().expect("points").truncate(4);
    }
    serde_json::to_string(&v).expect("json")
}

fn one_line(e: &dyn std::fmt::Display, file: &str) -> Result<(), TestCaseError> {
    let msg = e.to_string();
    prop_assert!(!msg.contains('\n'), "more than one line: {msg:?}");
    prop_assert!(msg.contains(file), "{file:?} not named: {msg}");
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn calibration_parser(text in inputs(EXAMPLE_CALIBRATION.to_string())) {
        match Calibration::parse(&text, Path::new("SN-fuzz.conf")) {
            Err(e) => one_line(&e, "SN-fuzz.conf")?,
            Ok(cal) => {
                for res in cal.resolutions() {
                    let rig = cal.rig(res).expect("a listed resolution has a rig");
                    for eye in [&rig.left, &rig.right] {
                        prop_assert!(eye.fx > 0.0 && eye.fy > 0.0 && eye.fx.is_finite() && eye.fy.is_finite());
                        prop_assert!([eye.cx, eye.cy, eye.k1, eye.k2, eye.p1, eye.p2, eye.k3].iter().all(|v| v.is_finite()));
                    }
                }
            }
        }
    }

    #[test]
    fn configuration_parser(text in inputs(DEFAULT_TOML.to_string())) {
        match Config::parse(&text, Path::new("fuzz.toml"), None) {
            // A calibration path the mutation made up is named instead of the file.
            Err(e) => one_line(&e, if e.to_string().contains("cannot read") { "" } else { "fuzz.toml" })?,
            Ok(c) => {
                let s = c.search;
                for r in [s.x_mm, s.y_mm, s.z_mm, s.size_mm, s.aspect_k] {
                    prop_assert!(r[0].is_finite() && r[1].is_finite() && r[0] < r[1], "{r:?}");
                }
                prop_assert!(s.z_mm[0] > 0.0 && s.size_mm[0] > 0.0 && s.aspect_k[0] > 0.0);
                prop_assert!(c.ga.population >= 4 && c.tracking.population >= 4);
                let t = &c.tracking;
                prop_assert!(t.lost_fitness >= 0.0 && t.lost_fitness <= t.min_fitness && t.min_fitness.is_finite());
                prop_assert!((0.0..=1.0).contains(&t.min_fitness_share));
            }
        }
    }

    #[test]
    fn model_parser(text in inputs(small_model())) {
        match PhotoModel::parse(&text, Path::new("fuzz.model")) {
            Err(e) => one_line(&e, "fuzz.model")?,
            Ok(m) => {
                prop_assert!(!m.inner.is_empty());
                prop_assert!(m.l_p > 0.0 && m.b_p > 0.0 && m.l_p.is_finite() && m.b_p.is_finite());
                prop_assert!(m.inner.iter().all(|p| p.x.is_finite() && p.y.is_finite() && p.h < 180));
                prop_assert!(m.mean_hue.is_finite() && m.outer_width_px.is_finite());
            }
        }
    }

    /// A line of a replay's `frames.csv`.
    #[test]
    fn replay_frame_line_parser(line in inputs("3,1234567,000003.png,1.5,-2,650,0.96,0.26,0,0.05,180,159".to_string())) {
        if let Err(e) = FrameRecord::parse(&line) {
            prop_assert!(!e.contains('\n'), "{e}");
        }
    }

    /// Any header with any payload length: validation never panics, and a frame it
    /// passes can be read with the header's geometry.
    #[test]
    fn frame_validation_of_any_header(
        width in prop_oneof![any::<u32>(), 0u32..64],
        height in prop_oneof![any::<u32>(), 0u32..64],
        format in prop_oneof![any::<u32>(), 0u32..3],
        stride in prop_oneof![any::<u32>(), 0u32..512],
        len in prop_oneof![any::<usize>(), 0usize..32768],
    ) {
        let header = FrameHeader { width, height, pixel_format: format, row_stride: stride, ..Default::default() };
        if let Ok(f) = validate_frame(&header, len) {
            prop_assert_eq!(Some(f), PixelFormat::from_code(format));
            prop_assert!(width > 0 && height > 0);
            prop_assert!(stride as u64 >= 2 * width as u64 * f.bytes_per_pixel() as u64);
            prop_assert_eq!(len as u64, height as u64 * stride as u64);
        }
    }

    /// A consistent header passes; the same header on a payload one byte off, or with a
    /// stride one byte short of the row, does not; RGB8 frames that pass are complete.
    #[test]
    fn frame_validation_of_consistent_headers(
        width in 1u32..48,
        height in 1u32..48,
        yuyv in any::<bool>(),
        padding in 0u32..16,
        off in 1usize..64,
    ) {
        let format = if yuyv { PixelFormat::Yuyv } else { PixelFormat::Rgb8 };
        if yuyv && width % 2 == 1 {
            let odd = FrameHeader { width, height, pixel_format: format.code(), row_stride: 4 * width, ..Default::default() };
            prop_assert_eq!(validate_frame(&odd, (4 * width * height) as usize), Err(FrameFault::OddYuyvWidth { width }));
            return Ok(());
        }
        let row = 2 * width * format.bytes_per_pixel() as u32;
        let header = FrameHeader {
            width, height, pixel_format: format.code(), row_stride: row + padding, ..Default::default()
        };
        let len = (height * (row + padding)) as usize;
        prop_assert_eq!(validate_frame(&header, len), Ok(format));
        let too_long = validate_frame(&header, len + off);
        prop_assert!(matches!(too_long, Err(FrameFault::LengthMismatch { .. })), "{:?}", too_long);
        let too_short = validate_frame(&header, len.saturating_sub(off));
        prop_assert!(matches!(too_short, Err(FrameFault::LengthMismatch { .. })), "{:?}", too_short);
        let short_stride = FrameHeader { row_stride: row - 1, ..header };
        let short = validate_frame(&short_stride, len);
        prop_assert!(matches!(short, Err(FrameFault::StrideTooShort { .. })), "{:?}", short);
        // A frame that passes can be read with its header's geometry.
        let bytes = vec![0u8; len];
        let sbs = SbsBytes { bytes: &bytes, width: width as usize, height: height as usize, row_stride: header.row_stride as usize, format };
        prop_assert!(sbs.is_complete());
        prop_assert!(sbs.to_images().is_some());
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Damaged PNG and JPEG frames give an error naming the file, never a panic.
    #[test]
    fn damaged_images(png in any::<bool>(), edits in prop::collection::vec((any::<usize>(), any::<u8>()), 1..12), cut in any::<usize>()) {
        let mut bytes = if png { tiny_png() } else { tiny_jpeg() };
        for (at, b) in edits {
            let at = at % bytes.len();
            bytes[at] = b;
        }
        bytes.truncate(cut % (bytes.len() + 1));
        let dir = std::env::temp_dir().join(format!("photopose-fuzz-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let path = dir.join(if png { "frame.png" } else { "frame.jpg" });
        std::fs::write(&path, &bytes).expect("write");
        if let Err(e) = StereoImages::load_sbs(&path) {
            one_line(&e, "frame.")?;
        }
        let _ = std::fs::remove_file(&path);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Scene files of the synthetic camera.
    #[test]
    fn scene_parser(text in inputs(std::fs::read_to_string(scene_path()).expect("scene"))) {
        if let Err(e) = SceneSpec::from_toml_str(&text, &scene_path()) {
            one_line(&e, "rocket.toml")?;
        }
    }
}

fn scene_path() -> std::path::PathBuf {
    repo("config/scenes/rocket.toml")
}

fn encoded(format: image::ImageFormat) -> Vec<u8> {
    let img = image::RgbImage::from_fn(16, 8, |x, y| image::Rgb([x as u8 * 16, y as u8 * 32, 7]));
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, format).expect("encode");
    out.into_inner()
}

fn tiny_png() -> Vec<u8> {
    encoded(image::ImageFormat::Png)
}

fn tiny_jpeg() -> Vec<u8> {
    encoded(image::ImageFormat::Jpeg)
}

/// A frame whose size matches no calibrated resolution is an error, not a panic.
#[test]
fn frame_sizes_outside_the_calibration_are_errors() {
    let cal = Calibration::parse(EXAMPLE_CALIBRATION, Path::new("SN-example.conf")).expect("example");
    for (w, h) in [(0, 0), (1, 1), (1280, 0), (u32::MAX, u32::MAX), (1281, 720)] {
        let e = cal.rig_for_image(w, h).expect_err("not a ZED size");
        assert!(e.to_string().contains("matches no ZED resolution"), "{e}");
    }
    assert!(cal.rig_for_image(1280, 720).is_ok());
    assert_eq!(cal.resolutions().len(), Resolution::ALL.len());
}
