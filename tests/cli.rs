//! The `photopose` binary: the model → estimate pipeline on a rendered frame, the exact
//! JSON contract, reproducibility, and one-line errors on bad input.

use std::path::Path;
use std::process::{Command, Output};

use crate::common::{data, repo, scratch};

pub fn photopose(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_photopose"))
        .args(args)
        .env("RUST_LOG", "warn")
        .output()
        .expect("run photopose")
}

/// `photopose model` of the coffee cup with a given configuration file.
fn model_with_config(photo: &str, output: &str, config: &str) -> Output {
    photopose(&[
        "model",
        "--photo",
        photo,
        "--box",
        "149,22,279,289",
        "-o",
        output,
        "--config",
        config,
    ])
}

/// Asserts failure with exactly one stderr line containing every needle.
pub fn fails_with(out: &Output, needles: &[&str]) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "expected failure, got success: {err}");
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "one line expected: {err}");
    assert!(!err.contains("panicked"), "{err}");
    for n in needles {
        assert!(err.contains(n), "{n:?} missing from: {err}");
    }
}

#[test]
fn render_model_estimate_pipeline_writes_the_json_contract() {
    let dir = scratch("pipeline");
    let p = |f: &str| dir.join(f).display().to_string();
    let out = photopose(&[
        "render",
        "--scene",
        &repo("config/scenes/coffee.toml").display().to_string(),
        "-o",
        &p("frame.png"),
        "--truth",
        &p("truth.json"),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let out = photopose(&[
        "model",
        "--photo",
        &data("photos/coffee.jpg").display().to_string(),
        "--box",
        "149,22,279,289",
        "-o",
        &p("cup.model"),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let run = |json: &str| {
        let args = [
            "estimate",
            "--model",
            &p("cup.model"),
            "--sbs",
            &p("frame.png"),
            "--generations",
            "120",
            "--seed",
            "7",
            "--json",
            json,
        ];
        let out = photopose(&args);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        String::from_utf8_lossy(&out.stdout).to_string()
    };
    let table = run(&p("a.json"));
    // Table 2 layout: a header and rows for generation 100 and the last one.
    assert!(table.contains("generation") && table.contains("F"), "{table}");
    assert!(table.lines().any(|l| l.trim_start().starts_with("100 ")), "{table}");
    assert!(table.lines().any(|l| l.trim_start().starts_with("120 ")), "{table}");
    let a: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(p("a.json")).unwrap()).unwrap();
    let keys: Vec<&str> = a.as_object().unwrap().keys().map(String::as_str).collect();
    let mut expected = vec![
        "position_mm",
        "orientation_wxyz",
        "size_mm",
        "alpha",
        "k",
        "fitness",
        "fitness_left",
        "fitness_right",
        "generations",
        "frame",
        "found",
        "confidence",
    ];
    let mut got = keys.clone();
    got.sort();
    expected.sort();
    assert_eq!(got, expected);
    assert_eq!(a["frame"], "hand");
    assert_eq!(a["generations"], 120);
    assert_eq!(a["position_mm"].as_array().unwrap().len(), 3);
    let q: Vec<f64> = a["orientation_wxyz"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert!(q[0] >= 0.0 && (q.iter().map(|v| v * v).sum::<f64>() - 1.0).abs() < 1e-9);
    // Same seed, same result.
    run(&p("b.json"));
    assert_eq!(
        std::fs::read_to_string(p("a.json")).unwrap(),
        std::fs::read_to_string(p("b.json")).unwrap()
    );
    let truth: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(p("truth.json")).unwrap()).unwrap();
    assert_eq!(truth["frame"], "hand");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_input_gives_one_line_naming_the_file() {
    let dir = scratch("bad-input");
    let p = |f: &str| dir.join(f).display().to_string();
    let coffee = data("photos/coffee.jpg").display().to_string();
    // A valid model and a frame whose size matches no calibration section.
    assert!(photopose(&[
        "model",
        "--photo",
        &coffee,
        "--box",
        "149,22,279,289",
        "-o",
        &p("cup.model")
    ])
    .status
    .success());
    image::RgbImage::new(2000, 500).save(p("odd-size.png")).unwrap();
    fails_with(
        &photopose(&["estimate", "--model", &p("cup.model"), "--sbs", &p("odd-size.png")]),
        &["SN-example.conf", "1000x500", "matches no ZED resolution"],
    );
    // Missing and corrupt frames.
    fails_with(
        &photopose(&["estimate", "--model", &p("cup.model"), "--sbs", &p("missing.png")]),
        &["missing.png"],
    );
    std::fs::write(p("corrupt.png"), b"\x89PNG\r\n\x1a\n garbage").unwrap();
    fails_with(
        &photopose(&["estimate", "--model", &p("cup.model"), "--sbs", &p("corrupt.png")]),
        &["corrupt.png"],
    );
    // A box outside the photo, a malformed box, a corrupt model.
    fails_with(
        &photopose(&[
            "model",
            "--photo",
            &coffee,
            "--box",
            "500,300,200,200",
            "-o",
            &p("x.model"),
        ]),
        &["coffee.jpg", "does not lie inside the 600x400 photo"],
    );
    fails_with(
        &photopose(&["model", "--photo", &coffee, "--box", "1,2,3", "-o", &p("x.model")]),
        &["--box", "four integers"],
    );
    std::fs::write(p("broken.model"), "{").unwrap();
    fails_with(
        &photopose(&["estimate", "--model", &p("broken.model"), "--sbs", &p("odd-size.png")]),
        &["broken.model"],
    );
    // Malformed configuration and calibration.
    for (name, needle) in [
        ("invalid-inverted-range.toml", "z_mm"),
        ("invalid-nan.toml", "x_mm"),
        ("invalid-syntax.toml", "line 3"),
    ] {
        let cfg = data(format!("config/{name}")).display().to_string();
        fails_with(&model_with_config(&coffee, &p("x.model"), &cfg), &[name, needle]);
    }
    let cal = data("calibration/invalid-not-a-number.conf");
    std::fs::write(p("bad-cal.toml"), format!("[camera]\ncalibration = {cal:?}\n")).unwrap();
    fails_with(
        &model_with_config(&coffee, &p("x.model"), &p("bad-cal.toml")),
        &["invalid-not-a-number.conf"],
    );
    // A missing model or configuration: the file and the system's reason, said once.
    let missing = [
        photopose(&["estimate", "--model", &p("missing.model"), "--sbs", &p("odd-size.png")]),
        model_with_config(&coffee, &p("x.model"), &p("missing.toml")),
    ];
    for (out, file) in missing.iter().zip(["missing.model", "missing.toml"]) {
        let said = format!(
            "error: cannot read {}: No such file or directory (os error 2)\n",
            p(file)
        );
        assert_eq!(String::from_utf8_lossy(&out.stderr), said);
    }
    assert!(!Path::new(&p("x.model")).exists(), "nothing written on error");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bench_json_reports_every_figure() {
    let (frame, model) = (
        data("examples/rocket-frame.jpg").display().to_string(),
        data("examples/rocket.model").display().to_string(),
    );
    let out = photopose(&[
        "bench",
        "--sbs",
        &frame,
        "--model",
        &model,
        "--individuals",
        "300",
        "--threads",
        "2",
        "--frames",
        "6",
        "--json",
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).unwrap();
    assert_eq!(text.lines().count(), 1, "one JSON object: {text}");
    let r: serde_json::Value = serde_json::from_str(&text).unwrap();
    let m: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    let model_points = m["inner"].as_array().unwrap().len() + m["outer"].as_array().unwrap().len();
    assert_eq!(
        r["points_per_individual"],
        2 * model_points,
        "N_in + N_out points × 2 images"
    );
    assert_eq!(r["threads"], 2);
    assert_eq!(r["tracking_frames"], 6);
    assert_eq!(
        r["oneshot_generations"], 1000,
        "the one-shot runs the configured generations"
    );
    let num = |k: &str| r[k].as_f64().unwrap_or_else(|| panic!("no number {k} in {text}"));
    for k in [
        "points_per_s_1t",
        "points_per_s_all",
        "oneshot_s",
        "tracking_frame_p50_ms",
    ] {
        assert!(num(k) > 0.0 && num(k).is_finite(), "{k} = {}", num(k));
    }
    // The figures agree with each other.
    let ns = num("ns_per_point_1t");
    assert!(
        (ns * num("points_per_s_1t") * 1e-9 - 1.0).abs() < 1e-6,
        "ns per point {ns}"
    );
    assert!(num("tracking_frame_p99_ms") >= num("tracking_frame_p50_ms"));
    // The relocation after the acquisition re-reads the whole frame: more than a
    // tracking frame.
    assert!(num("tracking_relocation_ms") > num("tracking_frame_p50_ms"));
    let wrong = photopose(&["bench", "--sbs", &frame, "--model", &model, "--individuals", "0"]);
    assert!(!wrong.status.success());
    assert_eq!(
        String::from_utf8_lossy(&wrong.stderr).trim(),
        "error: --individuals must be ≥ 1 and --frames ≥ 3"
    );
}

/// Every class of bad input, one case each: exit status 1, exactly one line on stderr
/// naming the file and the problem, no panic, nothing written.
#[test]
fn each_bad_input_class_exits_with_one_line() {
    let dir = scratch("bad-input-classes");
    let p = |f: &str| dir.join(f).display().to_string();
    let write = |f: &str, text: &str| std::fs::write(p(f), text).unwrap();
    let coffee = data("photos/coffee.jpg").display().to_string();
    let example = std::fs::read_to_string(repo("config/SN-example.conf")).unwrap();
    // Calibration files, each named by a configuration next to it.
    let calibrations = [
        (
            "missing-section.conf",
            example.replace("[STEREO]", "[STEREO_OLD]"),
            "section [STEREO] is missing",
        ),
        (
            "missing-key.conf",
            example.replacen("cy=", "cz=", 1),
            "section [LEFT_CAM_2K] lacks key cy",
        ),
        (
            "not-a-number.conf",
            example.replacen("fx=", "fx=abc", 1),
            "for key fx is not a number",
        ),
        (
            "decimal-comma.conf",
            example.replacen("fx=1207.17", "fx=1207,17", 1),
            "value \"1207,17\" for key fx is not a number (the decimal separator is '.')",
        ),
        (
            "zero-focal.conf",
            example.replacen("fx=1207.17", "fx=0", 1),
            "value 0 for key fx must be positive",
        ),
    ];
    for (name, text, problem) in &calibrations {
        write(name, text);
        let cfg = format!("{name}.toml");
        write(&cfg, &format!("[camera]\ncalibration = {name:?}\n"));
        fails_with(&model_with_config(&coffee, &p("x.model"), &p(&cfg)), &[name, problem]);
    }
    // Configuration files.
    let configs = [
        (
            "unknown-key.toml",
            "[ga]\npopulaton = 50\n",
            "unknown field `populaton`, expected one of `mode`, `population`, `generations`, `seed`",
        ),
        (
            "nan.toml",
            "[search]\nx_mm = [nan, 300.0]\n",
            "[search] x_mm: [NaN, 300] must be finite numbers",
        ),
        (
            "inverted.toml",
            "[search]\nsize_mm = [400.0, 20.0]\n",
            "[search] size_mm: [400, 20] is empty or inverted",
        ),
        (
            "empty-range.toml",
            "[search]\nz_mm = [500.0, 500.0]\n",
            "[search] z_mm: [500, 500] is empty or inverted",
        ),
        (
            "population-0.toml",
            "[ga]\npopulation = 0\n",
            "[ga] population: 0 is too small (at least 4)",
        ),
        (
            "floor.toml",
            "[tracking]\nlost_fitness = 1.5\n",
            "[tracking] lost_fitness: 1.5 must lie in [0, min_fitness = 1]",
        ),
        (
            "share.toml",
            "[tracking]\nmin_fitness_share = 1.2\n",
            "[tracking] min_fitness_share: 1.2 must lie in [0, 1]",
        ),
    ];
    for (name, text, problem) in configs {
        write(name, text);
        fails_with(&model_with_config(&coffee, &p("x.model"), &p(name)), &[name, problem]);
    }
    // Model files, then frames, through `photopose estimate`.
    let model = std::fs::read_to_string(data("examples/rocket.model")).unwrap();
    let first = model.find("\"inner\":[").unwrap() + 9;
    let models = [
        (
            "truncated.model",
            model[..model.len() / 2].to_string(),
            "not a photopose model: EOF",
        ),
        (
            "version.model",
            model.replacen("\"version\":1", "\"version\":7", 1),
            "model format version 7 is not supported (this build reads 1)",
        ),
        (
            "nan-colour.model",
            format!("{}[0.0,0.0,NaN,1.0,1.0],{}", &model[..first], &model[first..]),
            "not a photopose model: expected value",
        ),
        (
            "bad-colour.model",
            format!("{}[0.0,0.0,300.0,1.0,1.0],{}", &model[..first], &model[first..]),
            "colour [300, 1, 1] outside H 0–179, S and V 0–255",
        ),
    ];
    let frame = data("examples/rocket-frame.jpg").display().to_string();
    for (name, text, problem) in &models {
        write(name, text);
        fails_with(
            &photopose(&["estimate", "--model", &p(name), "--sbs", &frame]),
            &[name, problem],
        );
    }
    let good_model = data("examples/rocket.model").display().to_string();
    write("corrupt.png", "\u{89}PNG\r\n\u{1a}\n garbage");
    write("empty.jpg", "");
    image::RgbImage::new(2 * 1280, 700).save(p("wrong-size.png")).unwrap();
    for (name, problem) in [
        ("corrupt.png", "cannot read image"),
        ("empty.jpg", "cannot read image"),
        (
            "wrong-size.png",
            "image size 1280x700 per eye matches no ZED resolution",
        ),
    ] {
        fails_with(
            &photopose(&[
                "estimate",
                "--model",
                &good_model,
                "--sbs",
                &p(name),
                "--generations",
                "10",
            ]),
            &[name, problem],
        );
    }
    assert!(!Path::new(&p("x.model")).exists(), "nothing written on error");
    std::fs::remove_dir_all(&dir).unwrap();
}
