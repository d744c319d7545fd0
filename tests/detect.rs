//! Building a photo-model with the detector. In every build: `photopose model` checks the
//! class name and says how to get a detector. With `--features detect` (after
//! tools/setup-detect): the coffee cup is found where a person would box it, the
//! photo-model built from that box estimates a rendered scene to the core accuracy, and
//! a missing or broken runtime or network gives one line.

use std::path::Path;

use crate::cli::{fails_with, photopose, scratch};
use crate::scenes::data;

#[test]
fn unknown_class_and_bad_min_score_are_one_line_errors() {
    let dir = scratch("detect-args");
    let out = dir.join("x.model").display().to_string();
    let coffee = data("photos/coffee.jpg").display().to_string();
    fails_with(
        &photopose(&["model", "--photo", &coffee, "--class", "cupp", "-o", &out]),
        &["\"cupp\" is not a COCO class", "did you mean \"cup\"", "toothbrush"],
    );
    fails_with(
        &photopose(&["model", "--photo", &coffee, "--min-score", "1.5", "-o", &out]),
        &["--min-score 1.5", "(0, 1]"],
    );
    assert!(!Path::new(&out).exists(), "nothing written on error");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[cfg(not(feature = "detect"))]
#[test]
fn without_the_feature_model_needs_a_box() {
    let dir = scratch("detect-off");
    let coffee = data("photos/coffee.jpg").display().to_string();
    let out = dir.join("x.model").display().to_string();
    fails_with(
        &photopose(&["model", "--photo", &coffee, "-o", &out]),
        &["--features detect", "tools/setup-detect", "--box"],
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[cfg(feature = "detect")]
mod with_detector {
    use std::path::Path;
    use std::process::Command;
    use std::time::Instant;

    use photopose::config::Config;
    use photopose::detect::{self, coco, Detector, Rect};
    use photopose::estimate;
    use photopose::model::PhotoModel;
    use photopose::pose::rotation_error_deg;

    use crate::cli::{fails_with, photopose, scratch};
    use crate::scenes::{self, data, Spec};

    /// The cup in coffee.jpg as a person boxes it.
    const REFERENCE: Rect = Rect {
        x0: 149.0,
        y0: 22.0,
        x1: 428.0,
        y1: 311.0,
    };

    fn detector(config: &Config) -> Detector {
        Detector::new(&config.detect).unwrap_or_else(|e| panic!("{e} (run tools/setup-detect first)"))
    }

    #[test]
    fn detector_finds_the_coffee_cup() {
        let config = Config::load(None).unwrap();
        let start = Instant::now();
        let mut detector = detector(&config);
        let loaded = start.elapsed().as_secs_f64() * 1e3;
        let photo = scenes::photo("coffee.jpg");
        let mut times = Vec::new();
        let mut detections = None;
        for _ in 0..5 {
            let start = Instant::now();
            detections = Some(detector.detect(&photo, config.detect.min_score).unwrap());
            times.push(start.elapsed().as_secs_f64() * 1e3);
        }
        let detections = detections.unwrap();
        times.sort_by(f64::total_cmp);
        let cup = detect::choose(
            &detections,
            Some(coco::class_id("cup").unwrap()),
            Path::new("coffee.jpg"),
            0.25,
        )
        .unwrap();
        let iou = cup.rect.iou(&REFERENCE);
        let (iw, ih) = detector.input_size();
        println!(
            "coffee.jpg: cup score {:.3} box ({:.1}, {:.1})–({:.1}, {:.1}), IoU {iou:.3} with the reference; \
             {iw}x{ih} input, detection {:.1} ms (median of 5, first {:.1} ms), model load {loaded:.0} ms",
            cup.score, cup.rect.x0, cup.rect.y0, cup.rect.x1, cup.rect.y1, times[2], times[0]
        );
        assert!(iou >= 0.8, "IoU {iou:.3} with the reference box");
        assert_eq!(detections.list[0].class_name(), "cup", "the cup is the best detection");
        assert!(cup.score > 0.4, "score {}", cup.score);
    }

    #[test]
    fn detected_model_estimates_a_rendered_scene() {
        let dir = scratch("detect-estimate");
        let p = |f: &str| dir.join(f).display().to_string();
        let out = photopose(&[
            "model",
            "--photo",
            &data("photos/coffee.jpg").display().to_string(),
            "--class",
            "cup",
            "--overlay",
            &p("cup-overlay.png"),
            "-o",
            &p("cup.model"),
        ]);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(stdout.contains("detected cup"), "{stdout}");
        let model = PhotoModel::load(Path::new(&p("cup.model"))).unwrap();
        let record = model.detection.clone().expect("detection recorded in the model");
        assert_eq!(record.class, "cup");
        let [x, y, w, h] = record.bbox;
        let iou = Rect {
            x0: x as f32,
            y0: y as f32,
            x1: (x + w) as f32,
            y1: (y + h) as f32,
        }
        .iou(&REFERENCE);
        assert!(iou >= 0.8, "IoU {iou:.3}");
        let overlay = image::open(p("cup-overlay.png")).unwrap();
        assert_eq!((overlay.width(), overlay.height()), (600, 400));

        // A clean HD scene of that box ~600 mm away in front of the collage wall.
        let b = model.bbox;
        let spec = Spec {
            name: "detected-cup-600",
            photo: "coffee.jpg",
            bbox: [b.x as i64, b.y as i64, b.w as i64, b.h as i64],
            position: [30.0, 20.0, 600.0],
            rotation_deg: [10.0, -5.0, 0.0],
            size_mm: [100.0, 100.0 * b.h as f64 / b.w as f64],
            hand_eye: false,
            noise: 0.0,
            brightness: 1.0,
            occluder: 0.0,
        };
        let r = scenes::render(&spec, 100);
        let outcome = estimate::run(
            &model,
            &r.images,
            &r.config,
            r.config.ga.generations,
            r.config.ga.seed,
            &mut |_| {},
        )
        .unwrap();
        let best = &outcome.best;
        let size = best.size_mm(model.l_p, model.b_p);
        let position = (best.position - r.hand_from_model.translation.vector).norm();
        let size_err = ((size[0] - spec.size_mm[0]).abs() / spec.size_mm[0])
            .max((size[1] - spec.size_mm[1]).abs() / spec.size_mm[1]);
        let rotation = rotation_error_deg(&best.rotation(), &r.hand_from_model.rotation);
        println!(
            "detected cup model ({},{},{},{}): position error {position:.1} mm, size error {:.1} %, rotation error {rotation:.1}°",
            b.x,
            b.y,
            b.w,
            b.h,
            size_err * 100.0
        );
        assert!(position <= 10.0, "position error {position:.1} mm");
        assert!(size_err <= 0.05, "size error {:.1} %", size_err * 100.0);
        assert!(rotation <= 5.0, "rotation error {rotation:.1}°");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn class_not_in_the_photo_names_photo_class_and_best_score() {
        let dir = scratch("detect-giraffe");
        let out = dir.join("x.model").display().to_string();
        let coffee = data("photos/coffee.jpg").display().to_string();
        fails_with(
            &photopose(&["model", "--photo", &coffee, "--class", "giraffe", "-o", &out]),
            &[
                "coffee.jpg",
                "no giraffe detected",
                "best giraffe score",
                "minimum score 0.25",
            ],
        );
        assert!(!Path::new(&out).exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// `photopose model` on the coffee photo with one environment variable set.
    fn model_with_env(args: &[&str], key: &str, value: &str) -> std::process::Output {
        let coffee = data("photos/coffee.jpg").display().to_string();
        Command::new(env!("CARGO_BIN_EXE_photopose"))
            .args(["model", "--photo", &coffee])
            .args(args)
            .env("RUST_LOG", "warn")
            .env(key, value)
            .output()
            .expect("run photopose")
    }

    #[test]
    fn missing_or_broken_runtime_and_network_are_one_line_errors() {
        let dir = scratch("detect-broken");
        let p = |f: &str| dir.join(f).display().to_string();
        let out = p("x.model");
        fails_with(
            &model_with_env(&["-o", &out], "ORT_DYLIB_PATH", &p("missing.so")),
            &[
                "ONNX Runtime library",
                "missing.so",
                "ORT_DYLIB_PATH",
                "tools/setup-detect",
            ],
        );
        std::fs::write(p("not-a-library.so"), "not a shared library").unwrap();
        fails_with(
            &model_with_env(&["-o", &out], "ORT_DYLIB_PATH", &p("not-a-library.so")),
            &["not-a-library.so"],
        );
        std::fs::write(p("missing-model.toml"), config_with_model("missing.onnx")).unwrap();
        fails_with(
            &photopose(&[
                "model",
                "--photo",
                &data("photos/coffee.jpg").display().to_string(),
                "--config",
                &p("missing-model.toml"),
                "-o",
                &out,
            ]),
            &["detector model", "missing.onnx", "not found"],
        );
        std::fs::write(p("broken.onnx"), "not a network").unwrap();
        std::fs::write(p("broken-model.toml"), config_with_model("broken.onnx")).unwrap();
        fails_with(
            &photopose(&[
                "model",
                "--photo",
                &data("photos/coffee.jpg").display().to_string(),
                "--config",
                &p("broken-model.toml"),
                "-o",
                &out,
            ]),
            &["broken.onnx"],
        );
        assert!(!Path::new(&out).exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A configuration with the repository's calibration and runtime and another network.
    fn config_with_model(model: &str) -> String {
        let calibration = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/SN-example.conf");
        let (library, _) = detect::library_path(&Config::load(None).unwrap().detect);
        format!("[camera]\ncalibration = {calibration:?}\n[detect]\nmodel = {model:?}\nonnxruntime = {library:?}\n")
    }

    /// `--box` wins over detection: no detection record.
    #[test]
    fn box_overrides_detection() {
        let dir = scratch("detect-box");
        let out = dir.join("b.model").display().to_string();
        let coffee = data("photos/coffee.jpg").display().to_string();
        let o = photopose(&[
            "model",
            "--photo",
            &coffee,
            "--box",
            "149,22,279,289",
            "--class",
            "cup",
            "-o",
            &out,
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let model = PhotoModel::load(Path::new(&out)).unwrap();
        assert_eq!(model.detection, None);
        assert_eq!((model.bbox.x, model.bbox.w), (149, 279));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
