//! Building a photo-model with the detector. In every build: `photopose model` checks the
//! class name and says how to get a detector. With `--features detect` (after
//! tools/setup-detect): the coffee cup is found where a person would box it, the
//! photo-model built from that box estimates rendered scenes to the core accuracy
//! (medians, as good as the hand box), other output layouts run, and a missing or broken
//! runtime or network gives one line.

use std::path::Path;

use crate::cli::{fails_with, photopose};
use crate::common::{data, scratch};

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
    use photopose::estimator::model::PhotoModel;
    use photopose::estimator::oneshot;
    use photopose::estimator::pose::rotation_error_deg;

    use crate::cli::{fails_with, photopose};
    use crate::common::{data, repo, scratch};
    use crate::scenes::{self, Spec};

    /// The cup in coffee.jpg as a person boxes it.
    const REFERENCE: Rect = Rect {
        x0: 149.0,
        y0: 22.0,
        x1: 428.0,
        y1: 311.0,
    };

    /// Card centre (left camera, mm) and intrinsic X-Y-Z rotation (degrees) of the
    /// scenes the detected model is estimated on: ~600 mm away, tilted up to 15°.
    const SCENES: [([f64; 3], [f64; 3]); 8] = [
        ([30.0, 20.0, 600.0], [10.0, -5.0, 0.0]),
        ([30.0, 20.0, 600.0], [10.0, -5.0, 0.0]),
        ([0.0, 0.0, 600.0], [0.0, 0.0, 0.0]),
        ([-40.0, 10.0, 620.0], [-10.0, 15.0, 0.0]),
        ([20.0, -30.0, 580.0], [15.0, 10.0, 5.0]),
        ([50.0, 30.0, 600.0], [5.0, -12.0, 0.0]),
        ([0.0, 40.0, 640.0], [-8.0, -8.0, 3.0]),
        ([-20.0, -10.0, 560.0], [12.0, 6.0, -4.0]),
    ];

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
        let first = times[0];
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
            cup.score, cup.rect.x0, cup.rect.y0, cup.rect.x1, cup.rect.y1, times[2], first
        );
        assert!(iou >= 0.8, "IoU {iou:.3} with the reference box");
        assert_eq!(detections.list[0].class_name(), "cup", "the cup is the best detection");
        assert!(cup.score > 0.4, "score {}", cup.score);
    }

    #[test]
    fn detected_model_estimates_rendered_scenes() {
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

        // Clean HD scenes ~600 mm away in front of the collage wall, each rendered from
        // the detected box and, for comparison, from the hand box.
        let b = model.bbox;
        let detected_box = [b.x as i64, b.y as i64, b.w as i64, b.h as i64];
        let hand_box = [149, 22, 279, 289];
        let mut rows = Vec::new();
        for (i, (position, rotation_deg)) in SCENES.into_iter().enumerate() {
            let mut row = Vec::new();
            for bbox in [detected_box, hand_box] {
                let spec = Spec {
                    name: "cup-600",
                    photo: "coffee.jpg",
                    bbox,
                    position,
                    rotation_deg,
                    size_mm: [100.0, 100.0 * bbox[3] as f64 / bbox[2] as f64],
                    hand_eye: false,
                    noise: 0.0,
                    brightness: 1.0,
                    occluder: 0.0,
                };
                let r = scenes::render(&spec, 100 + i as u64);
                // The detected scene is estimated with the model file `photopose model` wrote.
                let m = if bbox == detected_box { &model } else { &r.model };
                let c = &r.config;
                let outcome = oneshot::run(m, &r.images, c, c.ga.generations, c.ga.seed, &mut |_| {}).unwrap();
                let best = &outcome.best;
                let size = best.size_mm(m.l_p, m.b_p);
                row.push([
                    (best.position - r.hand_from_model.translation.vector).norm(),
                    ((size[0] - spec.size_mm[0]).abs() / spec.size_mm[0])
                        .max((size[1] - spec.size_mm[1]).abs() / spec.size_mm[1])
                        * 100.0,
                    rotation_error_deg(&best.rotation(), &r.hand_from_model.rotation),
                ]);
            }
            println!(
                "scene {i} at {position:?} mm, {rotation_deg:?}°: detected box {:.1} mm {:.1} % {:.1}° | hand box {:.1} mm {:.1} % {:.1}°",
                row[0][0], row[0][1], row[0][2], row[1][0], row[1][1], row[1][2]
            );
            rows.push(row);
        }
        let median = |model: usize, k: usize| {
            let mut v: Vec<f64> = rows.iter().map(|r| r[model][k]).collect();
            v.sort_by(f64::total_cmp);
            (v[v.len() / 2 - 1] + v[v.len() / 2]) / 2.0
        };
        let (position, size, rotation) = (median(0, 0), median(0, 1), median(0, 2));
        println!(
            "median over {} scenes: detected box ({},{},{},{}) {position:.1} mm, {size:.1} %, {rotation:.1}° | hand box {:.1} mm, {:.1} %, {:.1}°",
            rows.len(),
            b.x,
            b.y,
            b.w,
            b.h,
            median(1, 0),
            median(1, 1),
            median(1, 2)
        );
        assert!(position <= 10.0, "median position error {position:.1} mm");
        assert!(size <= 5.0, "median size error {size:.1} %");
        assert!(rotation <= 5.0, "median rotation error {rotation:.1}°");
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
        let calibration = repo("config/SN-example.conf");
        let (library, _) = detect::library_path(&Config::load(None).unwrap().detect);
        format!("[camera]\ncalibration = {calibration:?}\n[detect]\nmodel = {model:?}\nonnxruntime = {library:?}\n")
    }

    /// A hand-written ONNX network whose output is a constant tensor: input `images`
    /// `[1, 3, height, width]` with symbolic sides, output `output0` of `shape`.
    fn constant_network(shape: &[i64], data: &[f32]) -> Vec<u8> {
        fn varint(out: &mut Vec<u8>, mut v: u64) {
            while v >= 0x80 {
                out.push((v as u8) | 0x80);
                v >>= 7;
            }
            out.push(v as u8);
        }
        fn field(out: &mut Vec<u8>, number: u64, bytes: &[u8]) {
            varint(out, number << 3 | 2);
            varint(out, bytes.len() as u64);
            out.extend_from_slice(bytes);
        }
        fn int(out: &mut Vec<u8>, number: u64, v: u64) {
            varint(out, number << 3);
            varint(out, v);
        }
        // ValueInfoProto of a float tensor; a dimension is a value or a symbol.
        let value_info = |name: &str, dims: &[Result<i64, &str>]| {
            let mut shape = Vec::new();
            for d in dims {
                let mut dim = Vec::new();
                match d {
                    Ok(v) => int(&mut dim, 1, *v as u64),
                    Err(symbol) => field(&mut dim, 2, symbol.as_bytes()),
                }
                field(&mut shape, 1, &dim);
            }
            let mut tensor = Vec::new();
            int(&mut tensor, 1, 1); // FLOAT
            field(&mut tensor, 2, &shape);
            let mut ty = Vec::new();
            field(&mut ty, 1, &tensor);
            let mut info = Vec::new();
            field(&mut info, 1, name.as_bytes());
            field(&mut info, 2, &ty);
            info
        };
        let mut value = Vec::new();
        for d in shape {
            int(&mut value, 1, *d as u64);
        }
        int(&mut value, 2, 1); // FLOAT
        let raw: Vec<u8> = data.iter().flat_map(|v| v.to_le_bytes()).collect();
        field(&mut value, 9, &raw);
        let mut attribute = Vec::new();
        field(&mut attribute, 1, b"value");
        field(&mut attribute, 5, &value);
        int(&mut attribute, 20, 4); // TENSOR
        let mut node = Vec::new();
        field(&mut node, 2, b"output0");
        field(&mut node, 4, b"Constant");
        field(&mut node, 5, &attribute);
        let mut graph = Vec::new();
        field(&mut graph, 1, &node);
        field(&mut graph, 2, b"constant");
        field(
            &mut graph,
            11,
            &value_info("images", &[Ok(1), Ok(3), Err("height"), Err("width")]),
        );
        let out_dims: Vec<Result<i64, &str>> = shape.iter().map(|d| Ok(*d)).collect();
        field(&mut graph, 12, &value_info("output0", &out_dims));
        let mut opset = Vec::new();
        int(&mut opset, 2, 13);
        let mut model = Vec::new();
        int(&mut model, 1, 8); // IR version
        field(&mut model, 7, &graph);
        field(&mut model, 8, &opset);
        model
    }

    /// A YOLOv8-layout network of dynamic input size runs with `input_size`, and its
    /// boxes come back in photo pixels; an output of another shape is a one-line error.
    #[test]
    fn yolov8_layout_network_of_dynamic_size_runs() {
        let dir = scratch("detect-yolov8");
        let config = Config::load(None).unwrap();
        // Two boxes in 640 × 640 input pixels: a cup (0.9) and a person (0.3).
        let n = 2;
        let mut data = vec![0.0f32; 84 * n];
        for (i, (cx, cy, w, h, class, score)) in [
            (320.0, 300.0, 200.0, 150.0, 41, 0.9),
            (100.0, 200.0, 50.0, 80.0, 0, 0.3),
        ]
        .into_iter()
        .enumerate()
        {
            for (a, v) in [cx, cy, w, h].into_iter().enumerate() {
                data[a * n + i] = v;
            }
            data[(4 + class) * n + i] = score;
        }
        let path = dir.join("yolov8-like.onnx");
        std::fs::write(&path, constant_network(&[1, 84, n as i64], &data)).unwrap();
        let settings = photopose::detect::settings::DetectSettings {
            model: path.clone(),
            ..config.detect.clone()
        };
        let mut detector = detector_with(&settings);
        assert_eq!(detector.input_size(), (640, 640));
        let photo = scenes::photo("coffee.jpg");
        let found = detector.detect(&photo, 0.25).unwrap();
        let got: Vec<(String, f32)> = found.list.iter().map(|d| (d.class_name(), d.score)).collect();
        assert_eq!(got, vec![("cup".to_string(), 0.9), ("person".to_string(), 0.3)]);
        let lb = detect::letterbox::Letterbox::new(600, 400, 640, 640);
        let want = lb.to_photo(&Rect::from_center(320.0, 300.0, 200.0, 150.0));
        assert_eq!(found.list[0].rect, want);

        let path = dir.join("not-yolo.onnx");
        std::fs::write(&path, constant_network(&[1, 10, 3], &[0.0; 30])).unwrap();
        let settings = photopose::detect::settings::DetectSettings {
            model: path,
            ..config.detect.clone()
        };
        let e = detector_with(&settings).detect(&photo, 0.25).unwrap_err().to_string();
        assert!(
            e.contains("not-yolo.onnx: output shape [1, 10, 3] is not a YOLO layout"),
            "{e}"
        );
        assert!(!e.contains('\n'), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    fn detector_with(settings: &photopose::detect::settings::DetectSettings) -> Detector {
        Detector::new(settings).unwrap_or_else(|e| panic!("{e}"))
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
