//! Charts drawn into images: sizes, colours where the data is, and error cases.

use super::*;

fn series<'a>(label: &'a str, points: &'a [(f64, f64)], color: [u8; 3]) -> Series<'a> {
    Series { label, points, color }
}

fn line_panel<'a>(series: Vec<Series<'a>>) -> Panel<'a> {
    Panel {
        title: "t",
        x_label: "x",
        y_label: "y",
        series,
        ..Default::default()
    }
}

/// One panel drawn on `w` × `h`, with its data-to-pixel mapping.
fn drawn(panel: &Panel, w: u32, h: u32) -> (RgbImage, Cartesian2d<RangedCoordf64, RangedCoordf64>) {
    register_fonts().unwrap();
    let mut buf = vec![255u8; (w * h * 3) as usize];
    let mapping = {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        let mapping = draw_panel(&root, panel, legend_width(&legend_entries(panel)))
            .unwrap()
            .expect("room for a chart");
        root.present().unwrap();
        mapping
    };
    let img = RgbImage::from_raw(w, h, buf).unwrap();
    assert_eq!(img, panels(std::slice::from_ref(panel), w, h).unwrap());
    (img, mapping)
}

#[test]
fn tick_labels_use_the_decimals_the_step_needs() {
    let labels = |lo: f64, hi: f64, max: usize| -> Vec<String> {
        let f = TickFormat::new((lo, hi), max);
        let ticks = RangedCoordf64::from(lo..hi).key_points(max);
        ticks.iter().map(|&v| f.label(v)).collect()
    };
    assert_eq!(labels(0.0, 1.0, 6), ["0", "0.2", "0.4", "0.6", "0.8", "1.0"]);
    assert_eq!(labels(-10.0, 10.0, 3), ["-10", "0", "10"]);
    assert_eq!(labels(1e9, 3e9, 3), ["1e9", "2e9", "3e9"]);
    assert_eq!(labels(1.0e-7, 1.5e-7, 2), ["1.0e-7", "1.5e-7"]);
    assert_eq!(labels(575.0, 660.0, 8), ["580", "600", "620", "640", "660"]);
}

#[test]
fn zero_width_ranges_are_padded() {
    assert_eq!(pad((5.0, 5.0), 0.1), (4.5, 5.5));
    assert_eq!(pad((0.0, 0.0), 0.1), (-1.0, 1.0));
    assert_eq!(pad((0.0, 10.0), 0.1), (-1.0, 11.0));
}

#[test]
fn lines_break_at_non_finite_points() {
    let pts = [
        (0.0, 1.0),
        (1.0, f64::NAN),
        (2.0, 2.0),
        (3.0, 3.0),
        (f64::INFINITY, 0.0),
    ];
    let got: Vec<&[(f64, f64)]> = runs(&pts).collect();
    assert_eq!(got, [&pts[0..1], &pts[2..4]]);
}

#[test]
fn horizontal_line_lands_on_the_mapped_row() {
    let color = [200, 10, 10];
    let pts = [(0.0, 5.0), (10.0, 5.0)];
    let (img, map) = drawn(&line_panel(vec![series("", &pts, color)]), 400, 300);
    for x in [1.0, 5.0, 9.0] {
        let (col, row) = map.translate(&(x, 5.0));
        let (col, row) = (col as u32, row as u32);
        assert_eq!(img.get_pixel(col, row).0, color, "x = {x}");
        assert_ne!(img.get_pixel(col, row - 4).0, color, "line too thick at x = {x}");
        assert_ne!(img.get_pixel(col, row + 4).0, color, "line too thick at x = {x}");
    }
}

#[test]
fn legend_shows_each_series_colour() {
    let only_in_legend = [1, 2, 250];
    let pts = [(0.0, 1.0), (1.0, 2.0)];
    let panel = line_panel(vec![
        series("truth", &pts, PALETTE[0]),
        series("estimate", &[], only_in_legend),
    ]);
    let img = panels(&[panel], 400, 300).unwrap();
    assert!(img.pixels().any(|p| p.0 == only_in_legend));
    let unlabelled = line_panel(vec![series("", &[], only_in_legend)]);
    let img = panels(&[unlabelled], 400, 300).unwrap();
    assert!(!img.pixels().any(|p| p.0 == only_in_legend));
}

#[test]
fn histogram_bars_are_proportional_to_counts() {
    let values = [1.0, 1.0, 1.0, 1.0, 2.0, 2.0, 3.0, f64::NAN];
    let color = [10, 120, 30];
    let panel = histogram("latency", "ms", &values, 3, color);
    let counts: Vec<f64> = panel.bars.iter().map(|b| b.count).collect();
    assert_eq!(counts, [4.0, 2.0, 1.0]);
    assert_eq!((panel.bars[0].x0, panel.bars[2].x1), (1.0, 3.0));
    let (img, map) = drawn(&panel, 500, 400);
    let base = map.translate(&(1.0, 0.0)).1 as u32;
    for b in &panel.bars {
        let col = map.translate(&((b.x0 + b.x1) / 2.0, 0.0)).0 as u32;
        let h = (0..=base + 1)
            .rev()
            .skip_while(|&y| img.get_pixel(col, y).0 != color)
            .take_while(|&y| img.get_pixel(col, y).0 == color)
            .count() as i32;
        let top = map.translate(&(b.x0, b.count)).1;
        let expected = base as i32 - top + 1;
        assert!(
            (h - expected).abs() <= 1,
            "height {h} px for count {}, expected {expected}",
            b.count
        );
    }
}

#[test]
fn degenerate_inputs_still_give_the_requested_size() {
    let nan = [
        (0.0, f64::NAN),
        (1.0, 2.0),
        (f64::INFINITY, 3.0),
        (3.0, 1.0),
        (f64::NAN, f64::NAN),
    ];
    let constant = [(0.0, 5.0), (1.0, 5.0), (2.0, 5.0)];
    let single = [(3.0, 7.0)];
    let huge = [(0.0, 1e300), (1.0, -1e300), (2.0, f64::MAX)];
    let tiny = [(1e-300, 1e-310), (2e-300, 3e-310)];
    let all: [&[(f64, f64)]; 6] = [&[], &nan, &constant, &single, &huge, &tiny];
    let mut ps: Vec<Panel> = all
        .iter()
        .map(|&pts| line_panel(vec![series("", pts, PALETTE[1])]))
        .collect();
    for drawn in &ps[1..4] {
        let img = panels(std::slice::from_ref(drawn), 640, 400).unwrap();
        assert!(
            img.pixels().any(|p| p.0 == PALETTE[1]),
            "finite points of {:?}",
            drawn.series[0].points
        );
    }
    ps.push(histogram("h", "v", &[], 10, PALETTE[0]));
    ps.push(histogram("h", "v", &[2.0; 5], 0, PALETTE[0]));
    ps.push(histogram("h", "v", &[f64::NAN, 1e308, -1e308], 4, PALETTE[0]));
    for (w, h) in [(640, 2000), (200, 100), (7, 3), (0, 0)] {
        let img = panels(&ps, w, h).unwrap();
        assert_eq!(img.dimensions(), (w, h));
        for p in &ps {
            assert_eq!(panels(std::slice::from_ref(p), w, h).unwrap().dimensions(), (w, h));
        }
    }
    assert_eq!(panels(&[], 50, 40).unwrap().dimensions(), (50, 40));
    assert_eq!(histogram("h", "v", &[2.0; 5], 0, PALETTE[0]).bars.len(), 1);
}

#[test]
fn save_names_the_file_on_error_and_writes_a_png() {
    let img = panels(&[line_panel(Vec::new())], 64, 48).unwrap();
    let missing = std::env::temp_dir()
        .join("photopose-plot-no-such-dir")
        .join("chart.png");
    let err = save(&img, &missing).unwrap_err();
    assert!(err.to_string().contains(&missing.display().to_string()), "{err}");
    let path = std::env::temp_dir().join(format!("photopose-plot-test-{}.png", std::process::id()));
    save(&img, &path).unwrap();
    let back = image::open(&path).unwrap().to_rgb8();
    std::fs::remove_file(&path).unwrap();
    assert_eq!(back, img);
}
