//! `plot`: PNG charts without system libraries: stacked line panels and histograms.
//!
//! Charts are drawn with [`plotters`] on its pure-Rust bitmap backend, into an
//! [`image::RgbImage`]. Text is rasterised by `ab_glyph` in DejaVu Sans, embedded in the
//! binary from the `dejavu` crate, so neither building nor running needs fontconfig or
//! freetype. [`panels`] stacks [`Panel`]s vertically, each with its own axes, title,
//! axis labels and legend; a panel shows line [`Series`] and/or histogram [`Bar`]s (see
//! [`histogram`]); [`save`] writes a PNG. Non-finite points are skipped (a line breaks
//! there), empty or constant data get a padded range, and a panel too small to hold a
//! chart stays blank, so any input gives an image of the requested size.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use image::RgbImage;
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::{register_font, FontStyle};

/// Distinct line colours: blue, orange, green, red, purple (e.g. truth, estimate, ...).
pub const PALETTE: [[u8; 3]; 5] = [
    [31, 119, 180],
    [255, 127, 14],
    [44, 160, 44],
    [214, 39, 40],
    [148, 103, 189],
];

/// The font family every text is drawn in (registered by [`register_fonts`]).
const FONT: &str = "sans-serif";
const TEXT: RGBColor = RGBColor(40, 40, 40);
const AXIS: RGBColor = RGBColor(90, 90, 90);
const GRID: RGBColor = RGBColor(228, 228, 228);
const LINE_WIDTH: u32 = 2;
/// At most this many labelled ticks on the x axis, and on the y axis.
const X_TICKS: usize = 12;
const Y_TICKS: usize = 8;
/// Smallest panel, pixels, that fits title, tick labels and axis labels around a plot.
const MIN_PANEL: (u32, u32) = (200, 140);

/// One line: `(x, y)` points in drawing order, with its legend label (empty: not listed).
#[derive(Clone, Copy, Debug)]
pub struct Series<'a> {
    /// Legend entry; empty leaves the line out of the legend.
    pub label: &'a str,
    /// Data points; a non-finite coordinate breaks the line.
    pub points: &'a [(f64, f64)],
    /// Line colour, RGB.
    pub color: [u8; 3],
}

/// One histogram bar spanning `x0..x1` on the x axis, `count` high.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bar {
    /// Left edge, data units.
    pub x0: f64,
    /// Right edge, data units.
    pub x1: f64,
    /// Height: how many values fell into the bin.
    pub count: f64,
}

/// One chart with its own axes: lines (`series`) and/or bars (`bars`, filled with `bar_color`).
/// Build line panels with `..Default::default()` for the fields not needed.
#[derive(Clone, Debug, Default)]
pub struct Panel<'a> {
    /// Caption above the plot area.
    pub title: &'a str,
    /// Label under the x axis (quantity and unit).
    pub x_label: &'a str,
    /// Label along the y axis (quantity and unit).
    pub y_label: &'a str,
    /// Lines, drawn in order over the bars.
    pub series: Vec<Series<'a>>,
    /// Histogram bars; the legend shows their total count.
    pub bars: Vec<Bar>,
    /// Fill colour of the bars, RGB.
    pub bar_color: [u8; 3],
}

/// Why a chart could not be drawn or written.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// Encoding or writing the PNG failed (e.g. the directory does not exist).
    #[error("cannot write plot {}: {reason}", .path.display())]
    Write {
        /// The PNG file.
        path: PathBuf,
        /// The encoder's or the system's reason.
        reason: image::ImageError,
    },
    /// The embedded font could not be loaded.
    #[error("cannot load the chart font")]
    Font,
    /// Drawing a chart failed.
    #[error("cannot draw the chart {title:?}: {message}")]
    Draw {
        /// The chart's title.
        title: String,
        /// plotters' reason.
        message: String,
    },
}

/// Draws `panels` stacked top to bottom, each `height / panels.len()` high, on white.
pub fn panels(panels: &[Panel], width: u32, height: u32) -> Result<RgbImage, PlotError> {
    let mut buf = vec![255u8; width as usize * height as usize * 3];
    if !panels.is_empty() && width > 0 && height > 0 {
        register_fonts()?;
        let root = BitMapBackend::with_buffer(&mut buf, (width, height)).into_drawing_area();
        // One legend width for all, so the stacked plot areas line up.
        let legend_w = panels.iter().filter_map(|p| legend_width(&legend_entries(p))).max();
        for (area, panel) in root.split_evenly((panels.len(), 1)).iter().zip(panels) {
            draw_panel(area, panel, legend_w).map_err(|e| PlotError::Draw {
                title: panel.title.to_string(),
                message: e.to_string(),
            })?;
        }
        root.present().map_err(|e| PlotError::Draw {
            title: String::new(),
            message: e.to_string(),
        })?;
    }
    // Cannot fail: the buffer holds exactly width × height RGB pixels.
    RgbImage::from_raw(width, height, buf).ok_or_else(|| PlotError::Draw {
        title: String::new(),
        message: "image buffer of the wrong size".into(),
    })
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
        .map_err(|reason| PlotError::Write {
            path: path.to_path_buf(),
            reason,
        })
}

/// Registers the embedded DejaVu Sans as [`FONT`] with plotters, once per process.
fn register_fonts() -> Result<(), PlotError> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = REGISTERED.get_or_init(|| register_font(FONT, FontStyle::Normal, dejavu::sans::regular()).is_ok());
    if *ok {
        Ok(())
    } else {
        Err(PlotError::Font)
    }
}

/// A [`PALETTE`]-style colour as plotters' colour.
fn rgb([r, g, b]: [u8; 3]) -> RGBColor {
    RGBColor(r, g, b)
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

/// What a panel's axes show.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Extent {
    /// The data ranges: x padded 1 %, y padded 6 % (bars start at 0).
    Data { x: (f64, f64), y: (f64, f64) },
    /// No finite point or bar.
    Empty,
    /// The data span more than an `f64` can hold.
    TooWide,
}

/// The axes' ranges for the finite points and bars of `p`.
fn extent(p: &Panel) -> Extent {
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
    let x = span(pts().map(|pt| pt.0).chain(bars().flat_map(|b| [b.x0, b.x1])));
    let y = span(pts().map(|pt| pt.1).chain(bars().flat_map(|b| [0.0, b.count])));
    let (Some(x), Some(y)) = (x, y) else {
        return Extent::Empty;
    };
    let (mut y0, y1) = pad(y, 0.06);
    if bars().next().is_some() && y.0 >= 0.0 {
        y0 = 0.0;
    }
    let (x, y) = (pad(x, 0.01), (y0, y1));
    if [x.1 - x.0, y.1 - y.0].iter().all(|w| w.is_finite()) {
        Extent::Data { x, y }
    } else {
        Extent::TooWide
    }
}

/// Tick labels with as many decimals as the tick step needs; scientific notation for
/// huge values or tiny steps.
struct TickFormat {
    step: f64,
    largest: f64,
}

impl TickFormat {
    /// The format of the ticks plotters puts on `range` (at most `max` of them).
    fn new(range: (f64, f64), max: usize) -> Self {
        let ticks = RangedCoordf64::from(range.0..range.1).key_points(max);
        let step = match ticks[..] {
            [a, b, ..] => b - a,
            [a] => a.abs(),
            [] => 1.0,
        };
        let largest = ticks.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        Self {
            step: if step > 0.0 { step } else { 1.0 },
            largest,
        }
    }

    /// The label of tick value `v`.
    fn label(&self, v: f64) -> String {
        let step_exp = self.step.log10().floor();
        if v == 0.0 {
            "0".into()
        } else if self.largest >= 1e6 || self.step < 1e-4 {
            let digits = (self.largest.log10().floor() - step_exp).clamp(0.0, 15.0) as usize;
            format!("{v:.digits$e}")
        } else {
            format!("{v:.*}", (-step_exp).clamp(0.0, 15.0) as usize)
        }
    }
}

/// The finite stretches of `points`: where a non-finite coordinate breaks the line.
fn runs(points: &[(f64, f64)]) -> impl Iterator<Item = &[(f64, f64)]> {
    points
        .split(|(x, y)| !(x.is_finite() && y.is_finite()))
        .filter(|run| !run.is_empty())
}

type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;
type DrawResult<T, DB> = Result<T, DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

/// Draws one panel into `area`: axes, grid, bars, lines, and the legend in a column
/// `legend_w` wide right of the plot. Returns the chart's data-to-pixel mapping, `None`
/// when the panel is too small to hold a chart.
fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    p: &Panel,
    legend_w: Option<u32>,
) -> DrawResult<Option<Cartesian2d<RangedCoordf64, RangedCoordf64>>, DB> {
    let (w, h) = area.dim_in_pixel();
    if w < MIN_PANEL.0 || h < MIN_PANEL.1 {
        return Ok(None);
    }
    let extent = extent(p);
    let (x, y) = match extent {
        Extent::Data { x, y } => (x, y),
        Extent::Empty | Extent::TooWide => ((0.0, 1.0), (0.0, 1.0)),
    };
    let mut chart = ChartBuilder::on(area)
        .caption(p.title, (FONT, 20).into_font().color(&TEXT))
        .margin(8)
        // Room for the legend right of the plot area, where it hides no data.
        .margin_right(legend_w.map_or(20, |w| w + 16))
        .x_label_area_size(44)
        .y_label_area_size(64)
        .build_cartesian_2d(x.0..x.1, y.0..y.1)?;
    let (x_ticks, y_ticks) = (TickFormat::new(x, X_TICKS), TickFormat::new(y, Y_TICKS));
    let (x_tick, y_tick) = (|v: &f64| x_ticks.label(*v), |v: &f64| y_ticks.label(*v));
    chart
        .configure_mesh()
        .x_desc(p.x_label)
        .y_desc(p.y_label)
        .label_style((FONT, 13).into_font().color(&TEXT))
        .axis_desc_style((FONT, 15).into_font().color(&TEXT))
        .axis_style(AXIS)
        .bold_line_style(GRID)
        .light_line_style(WHITE)
        .x_labels(X_TICKS)
        .y_labels(Y_TICKS)
        .x_label_formatter(&x_tick)
        .y_label_formatter(&y_tick)
        .draw()?;
    if let Extent::Data { .. } = extent {
        draw_bars(&mut chart, p)?;
        for s in &p.series {
            draw_series(&mut chart, s)?;
        }
    } else {
        let message = if extent == Extent::Empty {
            "no data"
        } else {
            "data out of range"
        };
        let style = (FONT, 24).into_font().color(&AXIS);
        let mid = (x.0 + (x.1 - x.0) * 0.4, (y.0 + y.1) / 2.0);
        chart.draw_series(std::iter::once(Text::new(message, mid, style)))?;
    }
    let (plot_x, plot_y) = chart.plotting_area().get_pixel_range();
    let base = area.get_base_pixel();
    draw_legend(
        area,
        (plot_x.end - base.0 + 12, plot_y.start - base.1),
        &legend_entries(p),
    )?;
    Ok(Some(chart.as_coord_spec().clone()))
}

/// A legend line: its label, colour and swatch (a line, or a box for bars).
struct LegendEntry {
    label: String,
    color: RGBColor,
    bar: bool,
}

/// The legend's lines: the labelled series, then the bars' total count.
fn legend_entries(p: &Panel) -> Vec<LegendEntry> {
    let mut entries: Vec<LegendEntry> = p
        .series
        .iter()
        .filter(|s| !s.label.is_empty())
        .map(|s| LegendEntry {
            label: s.label.to_string(),
            color: rgb(s.color),
            bar: false,
        })
        .collect();
    if !p.bars.is_empty() {
        let total: f64 = p.bars.iter().map(|b| b.count).filter(|c| c.is_finite()).sum();
        entries.push(LegendEntry {
            label: format!("n = {total}"),
            color: rgb(p.bar_color),
            bar: true,
        });
    }
    entries
}

/// Width of the legend box, pixels (about 8 px per character of 14 px text).
fn legend_width(entries: &[LegendEntry]) -> Option<u32> {
    entries.iter().map(|e| 8 * e.label.chars().count() as u32 + 48).max()
}

/// Draws the legend box with its top-left corner at `(x, y)` of `area`.
fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    (x, y): (i32, i32),
    entries: &[LegendEntry],
) -> DrawResult<(), DB> {
    let Some(w) = legend_width(entries) else {
        return Ok(());
    };
    const ROW: i32 = 20;
    let h = 8 + ROW * entries.len() as i32;
    area.draw(&Rectangle::new([(x, y), (x + w as i32, y + h)], WHITE.filled()))?;
    area.draw(&Rectangle::new(
        [(x, y), (x + w as i32, y + h)],
        RGBColor(170, 170, 170),
    ))?;
    let font = (FONT, 14)
        .into_font()
        .color(&TEXT)
        .pos(Pos::new(HPos::Left, VPos::Center));
    for (i, e) in entries.iter().enumerate() {
        let mid = y + 4 + ROW * i as i32 + ROW / 2;
        if e.bar {
            area.draw(&Rectangle::new([(x + 8, mid - 5), (x + 28, mid + 5)], e.color.filled()))?;
        } else {
            area.draw(&PathElement::new(
                [(x + 8, mid), (x + 28, mid)],
                e.color.stroke_width(LINE_WIDTH),
            ))?;
        }
        area.draw(&Text::new(e.label.as_str(), (x + 36, mid), font.clone()))?;
    }
    Ok(())
}

/// The bars of `p`.
fn draw_bars<DB: DrawingBackend>(chart: &mut Chart<'_, DB>, p: &Panel) -> DrawResult<(), DB> {
    if p.bars.is_empty() {
        return Ok(());
    }
    let color = rgb(p.bar_color);
    let bars = p
        .bars
        .iter()
        .filter(|b| b.x0.is_finite() && b.x1.is_finite() && b.count.is_finite())
        .map(|b| Rectangle::new([(b.x0, b.count), (b.x1, 0.0)], color.filled()));
    chart.draw_series(bars)?;
    Ok(())
}

/// One line, broken at non-finite points; an isolated point becomes a dot.
fn draw_series<DB: DrawingBackend>(chart: &mut Chart<'_, DB>, s: &Series) -> DrawResult<(), DB> {
    let color = rgb(s.color);
    for run in runs(s.points) {
        match run {
            [single] => chart.draw_series(std::iter::once(Circle::new(*single, 3, color.filled())))?,
            _ => chart.draw_series(LineSeries::new(run.iter().copied(), color.stroke_width(LINE_WIDTH)))?,
        };
    }
    Ok(())
}

#[cfg(test)]
mod tests;
