//! Tests of the calibration reader on valid and broken files.

use super::*;
use nalgebra::{Matrix3, Point3};

fn data(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

fn example() -> Calibration {
    Calibration::load(&data("config/SN-example.conf")).unwrap()
}

fn fixture(name: &str) -> Result<Calibration, CalibrationError> {
    Calibration::load(&data(&format!("tests/data/calibration/{name}")))
}

/// The right camera's centre in the left frame, recovered from `right_from_left`.
fn centre(rig: &StereoRig) -> Vector3<f64> {
    rig.right_from_left.inverse().translation.vector
}

const SIMPLE: &str = "[LEFT_CAM_HD]\nfx=700\nfy=700\ncx=640\ncy=360\nk1=0\nk2=0\np1=0\np2=0\nk3=0\n\
    [RIGHT_CAM_HD]\nfx=700\nfy=700\ncx=640\ncy=360\nk1=0\nk2=0\np1=0\np2=0\n\
    [STEREO]\nBaseline=120\nTY=0\nTZ=0\nCV_HD=0\nRX_HD=0\nRZ_HD=0\n";

fn simple_with(from: &str, to: &str) -> Result<Calibration, CalibrationError> {
    assert!(SIMPLE.contains(from), "{from}");
    Calibration::parse(&SIMPLE.replacen(from, to, 1), Path::new("SN7.conf"))
}

#[test]
fn example_file_has_all_resolutions() {
    let cal = example();
    assert_eq!(cal.resolutions(), Resolution::ALL.to_vec());
    assert!(cal.source().ends_with("config/SN-example.conf"));
    let hd = cal.rig(Resolution::HD).unwrap();
    assert_eq!((hd.width, hd.height), (1280, 720));
    assert_eq!(hd.left.fx, 699.81);
    assert_eq!(hd.right.cy, 362.12);
    assert_eq!(hd.left.k3, -0.00108271);
    assert!((hd.baseline_mm() - 119.934).abs() < 0.01, "{}", hd.baseline_mm());
    let c = centre(&hd);
    assert!((c - Vector3::new(119.934, 0.0815, -0.298)).norm() < 1e-9, "{c}");
    for res in Resolution::ALL {
        let rig = cal.rig(res).unwrap();
        assert_eq!((rig.width, rig.height), res.size());
        // Focal length scales with the image width (±1 %).
        let ratio = rig.left.fx / hd.left.fx / (res.size().0 as f64 / 1280.0);
        assert!((ratio - 1.0).abs() < 0.05, "{res}: {ratio}");
    }
}

#[test]
fn right_from_left_maps_right_centre_to_origin() {
    let rig = example().rig(Resolution::HD).unwrap();
    let c = Point3::new(119.934, 0.0815, -0.298);
    assert!((rig.right_from_left * c).coords.norm() < 1e-9);
}

#[test]
fn point_on_left_axis_has_disparity_fb_over_z() {
    let rig = example().rig(Resolution::HD).unwrap();
    let (l, r) = rig.project_both(&Point3::new(0.0, 0.0, 700.0));
    let (l, r) = (l.unwrap(), r.unwrap());
    let disparity = (l.x - rig.left.cx) - (r.x - rig.right.cx);
    let expected = rig.left.fx * 119.934 / 700.0;
    // Lens distortion and the ~1 mrad rotation move it by < 1 px.
    assert!((disparity - expected).abs() < 1.5, "{disparity} vs {expected}");
    assert!((l.y - r.y).abs() < 6.0);

    // Without distortion and rotation it is exact.
    let rig = simple_with("", "").unwrap().rig(Resolution::HD).unwrap();
    let (l, r) = rig.project_both(&Point3::new(0.0, 0.0, 700.0));
    assert!((l.unwrap().x - r.unwrap().x - 120.0).abs() < 1e-9);
}

#[test]
fn rodrigues_matches_hand_computation() {
    let r = rodrigues(Vector3::new(0.0, std::f64::consts::FRAC_PI_2, 0.0));
    assert!((r * Vector3::x() - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-12);
    assert!((r * Vector3::z() - Vector3::x()).norm() < 1e-12);

    // R = I + sinθ·K + (1 − cosθ)·K² for unit axis k.
    let v: Vector3<f64> = Vector3::new(0.3, -0.2, 0.1);
    let theta = v.norm();
    let k = v / theta;
    let kx = Matrix3::new(0.0, -k.z, k.y, k.z, 0.0, -k.x, -k.y, k.x, 0.0);
    let hand = Matrix3::identity() + kx * theta.sin() + kx * kx * (1.0 - theta.cos());
    let got = rodrigues(v).to_rotation_matrix().into_inner();
    assert!((got - hand).norm() < 1e-12);
}

#[test]
fn rotation_vector_order_is_rx_cv_rz() {
    // CV is the rotation about y: R maps x → −z, so Rᵀ (right_from_left) maps x → z.
    let cal = simple_with("CV_HD=0", "CV_HD=1.5707963267948966").unwrap();
    let rig = cal.rig(Resolution::HD).unwrap();
    let rot = rig.right_from_left.rotation;
    assert!((rot * Vector3::x() - Vector3::z()).norm() < 1e-12);
    // X_R = Rᵀ(X_L − c): the left origin lands at −Rᵀc = −(0, 0, 120).
    let origin = rig.right_from_left * Point3::origin();
    assert!(
        (origin.coords - Vector3::new(0.0, 0.0, -120.0)).norm() < 1e-9,
        "{origin}"
    );
}

#[test]
fn suffixed_keys_win_and_names_are_case_insensitive() {
    let text = std::fs::read_to_string(data("tests/data/calibration/valid-suffixed.conf")).unwrap();
    assert!(text.contains("\r\n"), "fixture must keep CRLF line endings");
    let cal = fixture("valid-suffixed.conf").unwrap();
    assert_eq!(cal.resolutions(), vec![Resolution::FHD, Resolution::HD]);
    let hd = cal.rig(Resolution::HD).unwrap();
    assert!((centre(&hd) - Vector3::new(120.0, 0.08, -0.3)).norm() < 1e-9);
    let fhd = cal.rig(Resolution::FHD).unwrap();
    assert!((centre(&fhd) - Vector3::new(120.0, 0.5, -0.5)).norm() < 1e-9);
    assert_eq!(hd.left.fx, 700.5);
    assert_eq!(hd.right.fx, 701.5);
    assert_eq!(hd.right.cx, 638.5);
    assert_eq!(hd.right.k3, 0.0);
    let expected = rodrigues(Vector3::new(-0.0006, 0.002, 0.0003)).inverse();
    assert!(hd.right_from_left.rotation.angle_to(&expected) < 1e-12);
}

#[test]
fn hd_only_file_serves_hd_and_explains_others() {
    let cal = fixture("valid-hd-only.conf").unwrap();
    assert_eq!(cal.resolutions(), vec![Resolution::HD]);
    assert_eq!(cal.rig_for_image(1280, 720).unwrap().left.fx, 699.81);
    let msg = cal.rig(Resolution::FHD).unwrap_err().to_string();
    assert!(
        msg.ends_with("valid-hd-only.conf: no calibration for FHD (file has HD)"),
        "{msg}"
    );
}

#[test]
fn resolution_from_image_size() {
    for res in Resolution::ALL {
        let (w, h) = res.size();
        assert_eq!(Resolution::from_size(w, h), Some(res));
        assert_eq!(example().rig_for_image(w, h).unwrap().width, w);
    }
    assert_eq!(Resolution::from_size(720, 1280), None);
    for (name, res) in [
        ("2K", Resolution::R2K),
        ("hd2k", Resolution::R2K),
        ("Fhd", Resolution::FHD),
        ("HD1080", Resolution::FHD),
        (" hd ", Resolution::HD),
        ("HD720", Resolution::HD),
        ("vga", Resolution::VGA),
    ] {
        assert_eq!(Resolution::from_name(name), Some(res), "{name}");
    }
    assert!(Resolution::ALL
        .iter()
        .all(|&r| Resolution::from_name(r.name()) == Some(r)));
    assert_eq!(Resolution::from_name("8K"), None);
    let cal = Calibration::parse(SIMPLE, Path::new("SN12345.conf")).unwrap();
    assert_eq!(
        cal.rig_for_image(1000, 500).unwrap_err().to_string(),
        "SN12345.conf: image size 1000x500 per eye matches no ZED resolution \
         (2K 2208x1242, FHD 1920x1080, HD 1280x720, VGA 672x376)"
    );
    let msg = cal.rig_for_image(2560, 720).unwrap_err().to_string();
    assert!(msg.contains("side-by-side") && msg.contains("HD 1280x720"), "{msg}");
    assert_eq!(
        cal.rig(Resolution::FHD).unwrap_err().to_string(),
        "SN12345.conf: no calibration for FHD (file has HD)"
    );
}

#[test]
fn invalid_fixtures_name_file_and_problem() {
    for (name, problem) in [
        (
            "invalid-not-a-number.conf",
            "line 2: value \"abc\" for key fx is not a number",
        ),
        ("invalid-missing-key.conf", "section [LEFT_CAM_HD] lacks key cy"),
        ("invalid-no-sections.conf", "not a ZED calibration file"),
        (
            "invalid-nan.conf",
            "line 17: value \"nan\" for key k1 is not a finite number",
        ),
    ] {
        let msg = fixture(name).unwrap_err().to_string();
        assert!(msg.contains(name) && msg.contains(problem), "{name}: {msg}");
        assert!(!msg.contains('\n'), "{msg}");
    }
}

#[test]
fn other_problems_have_clear_messages() {
    let cases = [
        (
            simple_with("fy=700", "fy=0"),
            "SN7.conf: line 3: value 0 for key fy must be positive",
        ),
        (
            simple_with("Baseline=120", "Baseline=-120"),
            "line 21: value -120 for key Baseline must be positive",
        ),
        (
            simple_with("CV_HD=0", "CV_HD=inf"),
            "value \"inf\" for key CV_HD is not a finite number",
        ),
        (
            simple_with("k2=0", "k2=0\nK2=1"),
            "line 8: key K2 repeats in section [LEFT_CAM_HD] (first on line 7)",
        ),
        (simple_with("TY=0", ""), "section [STEREO] lacks key TY (or TY_HD)"),
        (simple_with("RX_HD=0", ""), "section [STEREO] lacks key RX_HD"),
        (simple_with("p2=0\nk3=0", "k3=0"), "section [LEFT_CAM_HD] lacks key p2"),
        (
            simple_with("[STEREO]", "[OTHER]"),
            "section [STEREO] is missing (needed for HD)",
        ),
        (
            simple_with("fx=700", "fx=699,81"),
            "line 2: value \"699,81\" for key fx is not a number (the decimal separator is '.')",
        ),
        (
            simple_with("fx=700", "fx=0"),
            "line 2: value 0 for key fx must be positive",
        ),
        (
            simple_with("fx=700", "fx 700"),
            "line 2: expected `key=value` or `[SECTION]`, found \"fx 700\"",
        ),
        (
            simple_with("[RIGHT_CAM_HD]", "[RIGHT_CAM_FHD]"),
            "no resolution is calibrated for both eyes",
        ),
        (
            Calibration::parse("", Path::new("SN7.conf")),
            "SN7.conf: not a ZED calibration file",
        ),
    ];
    for (result, problem) in cases {
        let msg = result.unwrap_err().to_string();
        assert!(msg.contains("SN7.conf") && msg.contains(problem), "{problem}: {msg}");
    }
    let cal = simple_with("", "[LEFT_CAM_VGA]\nfx=1\n").unwrap();
    let msg = cal.rig(Resolution::VGA).unwrap_err().to_string();
    assert_eq!(
        msg,
        "SN7.conf: no calibration for VGA: section [RIGHT_CAM_VGA] is missing (file has HD)"
    );
}

#[test]
fn tolerates_extra_keys_sections_comments_and_bom() {
    let text = format!(
        "\u{feff}; header\n[MISC]\nSensor_ID=1\nwhatever=x\n[LEFT_CAM_FHD1200]\nfx=oops\n{}",
        SIMPLE.replace("k1=0", "k1 = 0 ; c\nk4=7\ns1=x\ntx=1")
    );
    let cal = Calibration::parse(&text, Path::new("a.conf")).unwrap();
    assert_eq!(cal.resolutions(), vec![Resolution::HD]);
}

#[test]
fn missing_file_error() {
    let msg = Calibration::load(Path::new("/nonexistent/SN1.conf"))
        .unwrap_err()
        .to_string();
    assert_eq!(msg, "cannot read /nonexistent/SN1.conf: No such file or directory");
}

#[test]
fn never_panics_on_damaged_input() {
    let text = std::fs::read_to_string(data("config/SN-example.conf")).unwrap();
    let path = Path::new("x.conf");
    for (i, _) in text.char_indices().step_by(7) {
        let _ = Calibration::parse(&text[..i], path);
        let _ = Calibration::parse(&text[i..], path);
    }
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    for _ in 0..2000 {
        let bytes: Vec<u8> = (0..64)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                b"[]=#;\r\n _xfkLEFT_CAM_HD.0-9e\xff"[(state % 29) as usize]
            })
            .collect();
        let _ = Calibration::parse(&String::from_utf8_lossy(&bytes), path);
    }
}
