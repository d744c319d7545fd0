//! `plot`: PNG charts without system libraries: stacked line panels and histograms.
//!
//! Charts are drawn into an [`image::RgbImage`] with the 8×8 bitmap font of [`font8x8`], so
//! no fontconfig or freetype is needed. [`panels`] stacks [`Panel`]s vertically, each with its
//! own axes; a panel shows line [`Series`] and/or histogram [`Bar`]s (see [`histogram`]);
//! [`save`] writes a PNG. Non-finite points are skipped (a line breaks there) and empty or
//! constant data get a padded range, so any input gives an image of the requested size.

use std::path::{Path, PathBuf};

use font8x8::legacy::{BASIC_LEGACY, LATIN_LEGACY};
use image::{Rgb, RgbImage};

/// Distinct line colours: blue, orange, green, red, purple (e.g. truth, estimate, ...).
pub const PALETTE: [[u8; 3]; 5] = [
    [31, 119, 180],
    [255, 127, 14],
    [44, 160, 44],
    [214, 39, 40],
    [148, 103, 189],
];

const TEXT: [u8; 3] = [40, 40, 40];
const AXIS: [u8; 3] = [90, 90, 90];
const GRID: [u8; 3] = [228, 228, 228];
const LINE_WIDTH: f64 = 2.2;

/// One line: `(x, y)` points in drawing order, with its legend label (empty: not listed).
#[derive(Clone, Copy, Debug)]
pub struct Series<'a> {
    pub label: &'a str,
    pub points: &'a [(f64, f64)],
    pub color: [u8; 3],
}

/// One histogram bar spanning `x0..x1` on the x axis, `count` high.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bar {
    pub x0: f64,
    pub x1: f64,
    pub count: f64,
}

/// One chart with its own axes: lines (`series`) and/or bars (`bars`, filled with `bar_color`).
/// Build line panels with `..Default::default()` for the fields not needed.
#[derive(Clone, Debug, Default)]
pub struct Panel<'a> {
    pub title: &'a str,
    pub x_label: &'a str,
    pub y_label: &'a str,
    pub series: Vec<Series<'a>>,
    pub bars: Vec<Bar>,
    pub bar_color: [u8; 3],
}

/// Why a chart could not be written.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// Encoding or writing the PNG failed (e.g. the directory does not exist).
    #[error("cannot write plot {}: {source}", .path.display())]
    Write { path: PathBuf, source: image::ImageError },
}

/// Draws `panels` stacked top to bottom, each `height / panels.len()` high, on white.
pub fn panels(panels: &[Panel], width: u32, height: u32) -> RgbImage {
    let mut img = RgbImage::from_pixel(width, height, Rgb([255; 3]));
    let n = panels.len() as i64;
    for (i, panel) in panels.iter().enumerate() {
        let (i, h) = (i as i64, i64::from(height));
        let region = rect(0, i * h / n, i64::from(width) - 1, (i + 1) * h / n - 1);
        draw_panel(&mut img, panel, &layout(panel, region));
    }
    img
}

/// A histogram panel of the finite `values` in `bins` equal bins (at least one), count on y.
pub fn histogram<'a>(title: &'a str, x_label: &'a str, values: &[f64], bins: usize, color: [u8; 3]) -> Panel<'a> {
    let bins = bins.max(1);
    let finite = || values.iter().copied().filter(|v| v.is_finite());
    let mut bars = Vec::new();
    if let Some(span) = span(finite()) {
        let (lo, hi) = pad(span, 0.0);
        let w = (hi - lo) / bins as f64;
        let mut counts = vec![0usize; bins];
        for v in finite() {
            counts[(((v - lo) / w) as usize).min(bins - 1)] += 1;
        }
        let edge = |i: usize| if i == bins { hi } else { lo + i as f64 * w };
        bars = (0..bins)
            .map(|i| Bar {
                x0: edge(i),
                x1: edge(i + 1),
                count: counts[i] as f64,
            })
            .collect();
    }
    Panel {
        title,
        x_label,
        y_label: "count",
        bars,
        bar_color: color,
        ..Default::default()
    }
}

/// Writes `img` as a PNG to `path`.
pub fn save(img: &RgbImage, path: &Path) -> Result<(), PlotError> {
    img.save_with_format(path, image::ImageFormat::Png)
        .map_err(|source| PlotError::Write {
            path: path.to_path_buf(),
            source,
        })
}

/// Pixel rectangle, bounds inclusive.
#[derive(Clone, Copy, Debug)]
struct Rect {
    x0: i64,
    y0: i64,
    x1: i64,
    y1: i64,
}

fn rect(x0: i64, y0: i64, x1: i64, y1: i64) -> Rect {
    Rect { x0, y0, x1, y1 }
}

/// Where a panel (`region`) puts its plot area, and the data ranges and ticks it shows.
struct Axes {
    region: Rect,
    plot: Rect,
    x: (f64, f64),
    y: (f64, f64),
    x_ticks: Vec<f64>,
    y_ticks: Vec<f64>,
    has_data: bool,
}

impl Axes {
    /// Data x → pixel column (fractional).
    fn px(&self, x: f64) -> f64 {
        self.plot.x0 as f64 + (x - self.x.0) / (self.x.1 - self.x.0) * (self.plot.x1 - self.plot.x0) as f64
    }
    /// Data y → pixel row (fractional; rows grow downwards).
    fn py(&self, y: f64) -> f64 {
        self.plot.y1 as f64 - (y - self.y.0) / (self.y.1 - self.y.0) * (self.plot.y1 - self.plot.y0) as f64
    }
}

/// Smallest and largest finite value, if any.
fn span(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    values.filter(|v| v.is_finite()).fold(None, |acc, v| match acc {
        None => Some((v, v)),
        Some((lo, hi)) => Some((v.min(lo), v.max(hi))),
    })
}

/// Widens `lo..hi` by `frac` of its width on each side; a zero width gets ±10 % (or ±1 at 0).
fn pad((lo, hi): (f64, f64), frac: f64) -> (f64, f64) {
    if hi - lo > lo.abs().max(hi.abs()) * 1e-12 {
        let d = (hi - lo) * frac;
        (lo - d, hi + d)
    } else {
        let d = if lo.abs() > 0.0 { lo.abs() * 0.1 } else { 1.0 };
        (lo - d, hi + d)
    }
}

/// About `target` "nice" values (1, 2 or 5 × 10ⁿ apart) inside `lo..=hi`.
fn nice_ticks(lo: f64, hi: f64, target: usize) -> Vec<f64> {
    let raw = (hi - lo) / target.max(1) as f64;
    if !(raw.is_finite() && raw > 0.0) {
        return Vec::new();
    }
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|&s| s >= raw * (1.0 - 1e-9))
        .unwrap_or(10.0 * mag);
    let eps = step * 1e-9;
    let (k0, k1) = (((lo - eps) / step).ceil(), ((hi + eps) / step).floor());
    if !(k0.is_finite() && k1.is_finite() && (0.0..=100.0).contains(&(k1 - k0))) {
        return Vec::new();
    }
    (0..=(k1 - k0) as i64).map(|i| (k0 + i as f64) * step + 0.0).collect()
}

/// Tick labels with as many decimals as the step needs; scientific for huge or tiny values.
fn tick_labels(ticks: &[f64]) -> Vec<String> {
    let step = match ticks {
        [a, b, ..] => b - a,
        [a] => a.abs().max(1e-300),
        [] => 1.0,
    };
    let big = ticks.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let step_exp = step.log10().floor();
    ticks
        .iter()
        .map(|&v| match v {
            _ if v == 0.0 => "0".to_string(),
            _ if big >= 1e6 || step < 1e-4 => {
                let digits = (big.log10().floor() - step_exp).clamp(0.0, 15.0) as usize;
                format!("{v:.digits$e}")
            }
            _ => format!("{v:.*}", (-step_exp).clamp(0.0, 15.0) as usize),
        })
        .collect()
}

/// Data ranges of a panel: x padded 1 %, y padded 6 % (bars start at 0), `None` without data.
fn ranges(p: &Panel) -> Option<((f64, f64), (f64, f64))> {
    let pts = || {
        p.series
            .iter()
            .flat_map(|s| s.points.iter())
            .filter(|(x, y)| x.is_finite() && y.is_finite())
    };
    let bars = || {
        p.bars
            .iter()
            .filter(|b| b.x0.is_finite() && b.x1.is_finite() && b.count.is_finite())
    };
    let x = span(pts().map(|pt| pt.0).chain(bars().flat_map(|b| [b.x0, b.x1])))?;
    let y = span(pts().map(|pt| pt.1).chain(bars().flat_map(|b| [0.0, b.count])))?;
    let (mut y0, y1) = pad(y, 0.06);
    if bars().next().is_some() && y.0 >= 0.0 {
        y0 = 0.0;
    }
    Some((pad(x, 0.01), (y0, y1)))
}

/// Places the plot area inside `region`, leaving room for title, ticks and labels.
fn layout(p: &Panel, region: Rect) -> Axes {
    let ((x, y), has_data) = ranges(p).map_or((((0.0, 1.0), (0.0, 1.0)), false), |r| (r, true));
    let top = region.y0 + if p.title.is_empty() { 10 } else { 30 };
    let bottom = (region.y1 - 36).max(top + 1);
    let y_ticks = nice_ticks(y.0, y.1, ((bottom - top) / 36).clamp(2, 8) as usize);
    let label_w = tick_labels(&y_ticks)
        .iter()
        .map(|s| text_width(s, 1))
        .max()
        .unwrap_or(8);
    let left = region.x0 + 26 + label_w;
    let right = (region.x1 - 20).max(left + 1);
    let x_ticks = nice_ticks(x.0, x.1, ((right - left) / 90).clamp(2, 12) as usize);
    Axes {
        region,
        plot: rect(left, top, right, bottom),
        x,
        y,
        x_ticks,
        y_ticks,
        has_data,
    }
}

fn draw_panel(img: &mut RgbImage, p: &Panel, ax: &Axes) {
    let r = ax.plot;
    for &t in &ax.x_ticks {
        let x = ax.px(t).round() as i64;
        fill(img, rect(x, r.y0, x, r.y1), GRID);
    }
    for &t in &ax.y_ticks {
        let y = ax.py(t).round() as i64;
        fill(img, rect(r.x0, y, r.x1, y), GRID);
    }
    for b in &p.bars {
        let (x0, x1) = (ax.px(b.x0).round() as i64 + 1, ax.px(b.x1).round() as i64 - 1);
        let bar = rect(x0, ax.py(b.count).round() as i64, x1.max(x0), ax.py(0.0).round() as i64);
        fill(img, clip(bar, r), p.bar_color);
    }
    for s in &p.series {
        draw_series(img, s, ax);
    }
    for (x0, y0, x1, y1) in [
        (r.x0, r.y0, r.x1, r.y0),
        (r.x0, r.y1, r.x1, r.y1),
        (r.x0, r.y0, r.x0, r.y1),
    ] {
        fill(img, rect(x0, y0, x1, y1), AXIS);
    }
    fill(img, rect(r.x1, r.y0, r.x1, r.y1), AXIS);
    let mut free_from = i64::MIN;
    for (t, label) in ax.x_ticks.iter().zip(tick_labels(&ax.x_ticks)) {
        let x = ax.px(*t).round() as i64;
        fill(img, rect(x, r.y1, x, r.y1 + 4), AXIS);
        let lx = (x - text_width(&label, 1) / 2).min(i64::from(img.width()) - text_width(&label, 1) - 2);
        if lx >= free_from {
            text(img, lx, r.y1 + 8, &label, 1, TEXT);
            free_from = lx + text_width(&label, 1) + 8;
        }
    }
    for (t, label) in ax.y_ticks.iter().zip(tick_labels(&ax.y_ticks)) {
        let y = ax.py(*t).round() as i64;
        fill(img, rect(r.x0 - 4, y, r.x0, y), AXIS);
        text(img, r.x0 - 7 - text_width(&label, 1), y - 4, &label, 1, TEXT);
    }
    let mid_x = (r.x0 + r.x1) / 2;
    text(img, mid_x - text_width(p.x_label, 1) / 2, r.y1 + 22, p.x_label, 1, TEXT);
    let mid_y = (r.y0 + r.y1) / 2;
    let label_y = mid_y + text_width(p.y_label, 1) / 2;
    text_up(img, ax.region.x0 + 6, label_y, p.y_label, TEXT);
    text(img, mid_x - text_width(p.title, 2) / 2, r.y0 - 24, p.title, 2, TEXT);
    if !ax.has_data {
        text(img, mid_x - 56, mid_y - 8, "no data", 2, AXIS);
    }
    draw_legend(img, p, r);
}

/// Legend box in the top-right corner of the plot area: a colour swatch and label per entry.
fn draw_legend(img: &mut RgbImage, p: &Panel, r: Rect) {
    let total: f64 = p.bars.iter().map(|b| b.count).filter(|c| c.is_finite()).sum();
    let n_label = format!("n = {total}");
    let mut entries: Vec<(&str, [u8; 3])> = p
        .series
        .iter()
        .filter(|s| !s.label.is_empty())
        .map(|s| (s.label, s.color))
        .collect();
    if !p.bars.is_empty() {
        entries.push((&n_label, p.bar_color));
    }
    if entries.is_empty() {
        return;
    }
    let w = 40 + entries.iter().map(|e| text_width(e.0, 1)).max().unwrap_or(0);
    let bottom = r.y0 + 16 + 14 * entries.len() as i64;
    let b = rect(r.x1 - 10 - w, r.y0 + 10, r.x1 - 10, bottom);
    fill(img, b, [170; 3]);
    fill(img, rect(b.x0 + 1, b.y0 + 1, b.x1 - 1, b.y1 - 1), [255; 3]);
    for (i, (label, color)) in entries.into_iter().enumerate() {
        let y = b.y0 + 11 + 14 * i as i64;
        fill(img, rect(b.x0 + 8, y - 1, b.x0 + 27, y + 1), color);
        text(img, b.x0 + 34, y - 4, label, 1, TEXT);
    }
}

/// Anti-aliased polyline through the finite points of `s`, broken at non-finite ones;
/// an isolated point becomes a dot. Coverage is the max over segments, so joins stay even.
fn draw_series(img: &mut RgbImage, s: &Series, ax: &Axes) {
    let r = ax.plot;
    let (w, h) = ((r.x1 - r.x0 + 1).max(0) as usize, (r.y1 - r.y0 + 1).max(0) as usize);
    let mut cov = vec![0f32; w * h];
    let mut prev: Option<(f64, f64)> = None;
    for (i, &(x, y)) in s.points.iter().enumerate() {
        if !(x.is_finite() && y.is_finite()) {
            prev = None;
            continue;
        }
        let b = (ax.px(x), ax.py(y));
        let next_ok = s.points.get(i + 1).is_some_and(|(x, y)| x.is_finite() && y.is_finite());
        match prev {
            Some(a) => segment(&mut cov, r, a, b, LINE_WIDTH),
            None if !next_ok => segment(&mut cov, r, b, b, 3.0 * LINE_WIDTH),
            None => {}
        }
        prev = Some(b);
    }
    for (i, &c) in cov.iter().enumerate() {
        if c > 0.0 {
            blend(img, r.x0 + (i % w) as i64, r.y0 + (i / w) as i64, s.color, f64::from(c));
        }
    }
}

/// Adds the coverage of a `width` wide segment `a`–`b` (pixel coordinates) to `cov` over `r`.
fn segment(cov: &mut [f32], r: Rect, a: (f64, f64), b: (f64, f64), width: f64) {
    if ![a.0, a.1, b.0, b.1].iter().all(|v| v.is_finite()) {
        return;
    }
    let rad = width / 2.0 + 1.0;
    let lim = |v: f64, lo: i64, hi: i64| v.clamp(lo as f64, hi as f64) as i64;
    let (x0, x1) = (lim(a.0.min(b.0) - rad, r.x0, r.x1), lim(a.0.max(b.0) + rad, r.x0, r.x1));
    let (y0, y1) = (lim(a.1.min(b.1) - rad, r.y0, r.y1), lim(a.1.max(b.1) + rad, r.y0, r.y1));
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let len2 = dx * dx + dy * dy;
    let w = r.x1 - r.x0 + 1;
    for y in y0..=y1 {
        for x in x0..=x1 {
            let (qx, qy) = (x as f64 - a.0, y as f64 - a.1);
            let t = ((qx * dx + qy * dy) / len2.max(f64::MIN_POSITIVE)).clamp(0.0, 1.0);
            let d = (qx - t * dx).hypot(qy - t * dy);
            let c = (width / 2.0 + 0.5 - d).clamp(0.0, 1.0) as f32;
            if let Some(v) = cov.get_mut(((y - r.y0) * w + x - r.x0) as usize) {
                *v = v.max(c);
            }
        }
    }
}

fn clip(a: Rect, b: Rect) -> Rect {
    rect(a.x0.max(b.x0), a.y0.max(b.y0), a.x1.min(b.x1), a.y1.min(b.y1))
}

fn bounds(img: &RgbImage) -> Rect {
    rect(0, 0, i64::from(img.width()) - 1, i64::from(img.height()) - 1)
}

fn blend(img: &mut RgbImage, x: i64, y: i64, c: [u8; 3], alpha: f64) {
    let (Ok(x), Ok(y)) = (u32::try_from(x), u32::try_from(y)) else {
        return;
    };
    if let Some(p) = img.get_pixel_mut_checked(x, y) {
        for (dst, src) in p.0.iter_mut().zip(c) {
            *dst = (f64::from(*dst) * (1.0 - alpha) + f64::from(src) * alpha).round() as u8;
        }
    }
}

/// Fills `r` (clipped to the image) with `c`.
fn fill(img: &mut RgbImage, r: Rect, c: [u8; 3]) {
    let r = clip(r, bounds(img));
    for y in r.y0..=r.y1 {
        for x in r.x0..=r.x1 {
            img.put_pixel(x as u32, y as u32, Rgb(c));
        }
    }
}

/// The 8×8 glyph of `ch` (ASCII and Latin-1; others show as `?`); bit `i` of row `j` is pixel (i, j).
fn glyph(ch: char) -> [u8; 8] {
    match ch as usize {
        c @ 0x20..=0x7e => BASIC_LEGACY[c],
        c @ 0xa0..=0xff => LATIN_LEGACY[c - 0xa0],
        _ => BASIC_LEGACY[usize::from(b'?')],
    }
}

fn text_width(s: &str, scale: i64) -> i64 {
    s.chars().count() as i64 * 8 * scale
}

/// Draws `s` with its top-left corner at `(x, y)`, each font pixel `scale` × `scale`.
fn text(img: &mut RgbImage, x: i64, y: i64, s: &str, scale: i64, c: [u8; 3]) {
    for (i, ch) in s.chars().enumerate() {
        for (gy, row) in glyph(ch).iter().enumerate() {
            for gx in (0..8).filter(|gx| row >> gx & 1 == 1) {
                let (px, py) = (x + (i as i64 * 8 + gx) * scale, y + gy as i64 * scale);
                fill(img, rect(px, py, px + scale - 1, py + scale - 1), c);
            }
        }
    }
}

/// Draws `s` rotated to read upwards, starting at bottom-left `(x, y)`.
fn text_up(img: &mut RgbImage, x: i64, y: i64, s: &str, c: [u8; 3]) {
    for (i, ch) in s.chars().enumerate() {
        for (gy, row) in glyph(ch).iter().enumerate() {
            for gx in (0..8).filter(|gx| row >> gx & 1 == 1) {
                blend(img, x + gy as i64, y - i as i64 * 8 - gx, c, 1.0);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: &[f64], b: &[f64]) -> bool {
        a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-9 * y.abs().max(1.0))
    }

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

    #[test]
    fn nice_ticks_on_hand_picked_ranges() {
        assert!(close(&nice_ticks(0.0, 1.0, 5), &[0.0, 0.2, 0.4, 0.6, 0.8, 1.0]));
        assert!(close(&nice_ticks(3.7, 12.1, 5), &[4.0, 6.0, 8.0, 10.0, 12.0]));
        assert!(close(&nice_ticks(-7.0, 7.0, 5), &[-5.0, 0.0, 5.0]));
        assert!(close(&nice_ticks(0.0, 1e9, 5), &[0.0, 2e8, 4e8, 6e8, 8e8, 1e9]));
        assert!(close(
            &nice_ticks(1.0e-7, 1.5e-7, 5),
            &[1.0e-7, 1.1e-7, 1.2e-7, 1.3e-7, 1.4e-7, 1.5e-7]
        ));
        assert!(nice_ticks(1.0, 1.0, 5).is_empty());
        assert!(nice_ticks(f64::NAN, 1.0, 5).is_empty());
        assert!(nice_ticks(-f64::MAX, f64::MAX, 5).is_empty());
    }

    #[test]
    fn tick_labels_use_the_decimals_the_step_needs() {
        assert_eq!(
            tick_labels(&nice_ticks(0.0, 1.0, 5)),
            ["0", "0.2", "0.4", "0.6", "0.8", "1.0"]
        );
        assert_eq!(tick_labels(&[-10.0, 0.0, 10.0]), ["-10", "0", "10"]);
        assert_eq!(tick_labels(&[1e9, 2e9, 3e9]), ["1e9", "2e9", "3e9"]);
        assert_eq!(tick_labels(&[1.0e-7, 1.5e-7]), ["1.0e-7", "1.5e-7"]);
    }

    #[test]
    fn zero_width_ranges_are_padded() {
        assert_eq!(pad((5.0, 5.0), 0.1), (4.5, 5.5));
        assert_eq!(pad((0.0, 0.0), 0.1), (-1.0, 1.0));
        assert_eq!(pad((0.0, 10.0), 0.1), (-1.0, 11.0));
    }

    #[test]
    fn horizontal_line_lands_on_the_mapped_row() {
        let color = [200, 10, 10];
        let pts = [(0.0, 5.0), (10.0, 5.0)];
        let panel = line_panel(vec![series("", &pts, color)]);
        let img = panels(std::slice::from_ref(&panel), 400, 300);
        let ax = layout(&panel, bounds(&img));
        let row = ax.py(5.0).round() as u32;
        for x in [1.0, 5.0, 9.0] {
            let col = ax.px(x).round() as u32;
            assert_eq!(img.get_pixel(col, row).0, color, "x = {x}");
            assert_ne!(img.get_pixel(col, row - 4).0, color, "line too thick at x = {x}");
            assert_ne!(img.get_pixel(col, row + 4).0, color, "line too thick at x = {x}");
        }
        // The other side of the mapping: data at the plot's edges maps to its corners.
        assert_eq!(ax.px(ax.x.0), ax.plot.x0 as f64);
        assert_eq!(ax.py(ax.y.1), ax.plot.y0 as f64);
    }

    #[test]
    fn legend_shows_each_series_colour() {
        let only_in_legend = [1, 2, 250];
        let pts = [(0.0, 1.0), (1.0, 2.0)];
        let panel = line_panel(vec![
            series("truth", &pts, PALETTE[0]),
            series("estimate", &[], only_in_legend),
        ]);
        let img = panels(&[panel], 400, 300);
        assert!(img.pixels().any(|p| p.0 == only_in_legend));
        let unlabelled = line_panel(vec![series("", &[], only_in_legend)]);
        assert!(!panels(&[unlabelled], 400, 300).pixels().any(|p| p.0 == only_in_legend));
    }

    #[test]
    fn histogram_bars_are_proportional_to_counts() {
        let values = [1.0, 1.0, 1.0, 1.0, 2.0, 2.0, 3.0, f64::NAN];
        let color = [10, 120, 30];
        let panel = histogram("latency", "ms", &values, 3, color);
        let counts: Vec<f64> = panel.bars.iter().map(|b| b.count).collect();
        assert_eq!(counts, [4.0, 2.0, 1.0]);
        assert_eq!((panel.bars[0].x0, panel.bars[2].x1), (1.0, 3.0));
        let img = panels(std::slice::from_ref(&panel), 500, 400);
        let ax = layout(&panel, bounds(&img));
        let base = ax.py(0.0).round() as u32;
        let heights: Vec<f64> = panel
            .bars
            .iter()
            .map(|b| {
                let col = ax.px((b.x0 + b.x1) / 2.0).round() as u32;
                (0..base)
                    .rev()
                    .take_while(|&y| img.get_pixel(col, y).0 == color)
                    .count() as f64
            })
            .collect();
        let unit = ax.py(0.0) - ax.py(1.0);
        for (h, c) in heights.iter().zip(&counts) {
            assert!((h - c * unit).abs() <= 1.5, "height {h} for count {c} (unit {unit} px)");
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
            let img = panels(std::slice::from_ref(drawn), 640, 400);
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
            let img = panels(&ps, w, h);
            assert_eq!(img.dimensions(), (w, h));
            for p in &ps {
                assert_eq!(panels(std::slice::from_ref(p), w, h).dimensions(), (w, h));
            }
        }
        assert_eq!(panels(&[], 50, 40).dimensions(), (50, 40));
        assert_eq!(histogram("h", "v", &[2.0; 5], 0, PALETTE[0]).bars.len(), 1);
    }

    #[test]
    fn save_names_the_file_on_error_and_writes_a_png() {
        let img = panels(&[line_panel(Vec::new())], 64, 48);
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
}
