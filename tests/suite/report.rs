//! The suite's table (printed and written as Markdown to `target/suite/suite.md`), its
//! summary per group, the verdict's precision and recall, the accuracy targets (reported)
//! and the floors and the verdict's promise (asserted).

use std::fmt::Write as _;

use photopose::estimator::verify::Verdict;

use crate::accuracy::{median, Errors};

/// Success: within 10 mm, 5 % and 5° of the truth.
const SUCCESS: Errors = Errors {
    position: 10.0,
    size: 0.05,
    rotation: 5.0,
};
/// The targets: shares of successes, and medians (mm, relative, degrees) per group.
const CLEAN_SUCCESS: f64 = 0.95;
const HARD_SUCCESS: f64 = 0.85;
const MEDIANS: Errors = Errors {
    position: 3.0,
    size: 0.02,
    rotation: 2.0,
};

/// Floors of the success shares, asserted against regressions: the shares measured on
/// 2026-12-02 on the 56 scenes, with points off the image judged by the visible part
/// (clean 33 of 33, hard 19 of 23) less two scenes. The search with other random streams has moved by one or two scenes
/// either way. The targets above are reported, not asserted, until they are reached.
const CLEAN_FLOOR: f64 = 0.93;
const HARD_FLOOR: f64 = 0.73;
/// A pose this far off must never be reported found: position mm, rotation degrees.
const WRONG_MM: f64 = 20.0;
const WRONG_DEG: f64 = 10.0;

/// One scene's results.
#[derive(Debug, Clone)]
pub struct Row {
    /// The scene's name.
    pub name: &'static str,
    /// A hard scene (noise, blur, light, white balance or occluder).
    pub hard: bool,
    /// `HD` or `FHD`.
    pub resolution: &'static str,
    /// The card's larger bounding-box side in the left image, px.
    pub extent_px: f64,
    /// Errors of the robust mode.
    pub robust: Errors,
    /// Errors of the paper mode.
    pub paper: Errors,
    /// The robust result's and the truth's score (the rank the search uses).
    pub score_result: f64,
    pub score_truth: f64,
    /// Seconds of the robust estimate.
    pub seconds: f64,
    /// The robust result's verdict.
    pub verdict: Verdict,
}

impl Row {
    /// The truth scores above what the search returned: the search missed the peak.
    pub fn truth_outranks(&self) -> bool {
        self.score_truth > self.score_result
    }

    /// The robust result is more than 20 mm or 10° off.
    pub fn wrong(&self) -> bool {
        self.robust.position > WRONG_MM || self.robust.rotation > WRONG_DEG
    }
}

/// Within the success bounds.
fn success(e: &Errors) -> bool {
    e.position <= SUCCESS.position && e.size <= SUCCESS.size && e.rotation <= SUCCESS.rotation
}

/// `e` as table cells: position mm, size %, rotation °.
fn cells(e: &Errors) -> [String; 3] {
    [
        format!("{:.1}", e.position),
        format!("{:.1}", e.size * 100.0),
        format!("{:.1}", e.rotation),
    ]
}

/// The header and one line per row, as Markdown table lines.
pub fn table(rows: &[Row]) -> Vec<String> {
    let mut lines = vec![
        "| scene | kind | res | px | pos mm | size % | rot ° | found | conf | stereo | struct | sharp | tilt px | paper pos | size % | rot ° | score | truth score | truth > result | s |"
            .to_string(),
        "|---|---|---|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|".to_string(),
    ];
    for r in rows {
        let [p, s, o] = cells(&r.robust);
        let [pp, ps, po] = cells(&r.paper);
        lines.push(format!(
            "| {} | {} | {} | {:.0} | {p} | {s} | {o} | {} | {:.2} | {:.3} | {:.3} | {:.3} | {:.2} | {pp} | {ps} | {po} | {:.3} | {:.3} | {} | {:.1} |",
            r.name,
            if r.hard { "hard" } else { "clean" },
            r.resolution,
            r.extent_px,
            if r.verdict.found { "yes" } else { "no" },
            r.verdict.confidence,
            r.verdict.texture.stereo,
            r.verdict.texture.structure,
            r.verdict.sharpness,
            r.verdict.tilt_px,
            r.score_result,
            r.score_truth,
            if r.truth_outranks() { "yes" } else { "" },
            r.seconds,
        ));
    }
    lines
}

/// One group's figures: successes and medians of the robust mode, successes of the
/// paper mode.
pub struct Summary {
    /// `clean` or `hard`.
    pub label: &'static str,
    /// Scenes in the group.
    pub count: usize,
    /// Share of robust estimates within the success bounds.
    pub success: f64,
    /// Robust medians of position (mm), size (relative) and rotation (°) errors.
    pub medians: Errors,
    /// Share of paper-mode estimates within the success bounds.
    pub paper_success: f64,
}

/// The summary of the rows with `hard` as given.
pub fn summary(rows: &[Row], hard: bool) -> Summary {
    let sel: Vec<&Row> = rows.iter().filter(|r| r.hard == hard).collect();
    let share = |n: usize, of: usize| n as f64 / of.max(1) as f64;
    let of = |f: fn(&Errors) -> f64| median(sel.iter().map(|r| f(&r.robust)).collect());
    Summary {
        label: if hard { "hard" } else { "clean" },
        count: sel.len(),
        success: share(sel.iter().filter(|r| success(&r.robust)).count(), sel.len()),
        medians: Errors {
            position: of(|e| e.position),
            size: of(|e| e.size),
            rotation: of(|e| e.rotation),
        },
        paper_success: share(sel.iter().filter(|r| success(&r.paper)).count(), sel.len()),
    }
}

/// The summary lines: per group, then the truth-outranks count and the wall time.
pub fn summary_lines(rows: &[Row], seconds: f64) -> Vec<String> {
    let mut lines = Vec::new();
    for s in [summary(rows, false), summary(rows, true)] {
        lines.push(format!(
            "{} ({} scenes): robust {:.0} % within 10 mm, 5 %, 5°, medians {:.1} mm, {:.1} %, {:.1}°; paper {:.0} % within",
            s.label,
            s.count,
            s.success * 100.0,
            s.medians.position,
            s.medians.size * 100.0,
            s.medians.rotation,
            s.paper_success * 100.0
        ));
    }
    lines.push(verdict_line(rows));
    let outranks = rows.iter().filter(|r| r.truth_outranks()).count();
    lines.push(format!(
        "truth outranks the robust result on {outranks} of {} scenes (the search missed a pose that scores higher, or the plane sweep or the lining up of the sides left the score's peak)",
        rows.len()
    ));
    lines.push(format!("total wall time {seconds:.0} s"));
    lines
}

/// The verdict's figures: how many results were reported found, how many of those were
/// within the success bounds (precision) and how many successes were reported found
/// (recall), and how many wrong poses were reported found.
fn verdict_line(rows: &[Row]) -> String {
    let found = rows.iter().filter(|r| r.verdict.found).count();
    let good = rows.iter().filter(|r| success(&r.robust)).count();
    let good_found = rows.iter().filter(|r| r.verdict.found && success(&r.robust)).count();
    let wrong = rows.iter().filter(|r| r.wrong()).count();
    let wrong_found = rows.iter().filter(|r| r.verdict.found && r.wrong()).count();
    format!(
        "verdict: {found} reported found, {good_found} of them within 10 mm, 5 %, 5° (precision {:.0} %), \
         recall {:.0} % of {good} such results; {wrong} results more than 20 mm or 10° off, {wrong_found} of them reported found",
        100.0 * good_found as f64 / found.max(1) as f64,
        100.0 * good_found as f64 / good.max(1) as f64,
    )
}

/// Writes the table and summary as Markdown to `target/suite/suite.md`.
pub fn write_markdown(rows: &[Row], seconds: f64) {
    let dir = crate::common::repo("target/suite");
    std::fs::create_dir_all(&dir).expect("target/suite");
    let mut text = table(rows).join("\n");
    text.push_str("\n\n");
    for line in summary_lines(rows, seconds) {
        let _ = writeln!(text, "- {line}");
    }
    std::fs::write(dir.join("suite.md"), text).expect("suite.md");
}

/// The targets (≥ 95 % of clean and ≥ 85 % of hard scenes within 10 mm, 5 %,
/// 5°; medians ≤ 3 mm, 2 %, 2°), one line each: reached or not, with the figure.
pub fn target_lines(rows: &[Row]) -> Vec<String> {
    let mut lines = Vec::new();
    for (hard, share) in [(false, CLEAN_SUCCESS), (true, HARD_SUCCESS)] {
        let s = summary(rows, hard);
        let m = &s.medians;
        let medians_met = m.position <= MEDIANS.position && m.size <= MEDIANS.size && m.rotation <= MEDIANS.rotation;
        let verdict = |met: bool| if met { "reached" } else { "NOT reached" };
        lines.push(format!(
            "target {}: {:.0} % within bounds (target {:.0} %): {}; medians {:.1} mm, {:.1} %, {:.1}° (target 3 mm, 2 %, 2°): {}",
            s.label,
            s.success * 100.0,
            share * 100.0,
            verdict(s.success >= share),
            m.position,
            m.size * 100.0,
            m.rotation,
            verdict(medians_met)
        ));
    }
    lines
}

/// What the suite asserts: no wrong pose reported found, and the success shares at or
/// above their floors.
pub fn assert_promises(rows: &[Row]) {
    assert_verdict(rows);
    for (hard, floor) in [(false, CLEAN_FLOOR), (true, HARD_FLOOR)] {
        let s = summary(rows, hard);
        assert!(
            s.success >= floor,
            "{}: {:.0} % within 10 mm, 5 %, 5°, below the floor of {:.0} %",
            s.label,
            s.success * 100.0,
            floor * 100.0
        );
    }
}

/// No result more than 20 mm or 10° off is reported found.
pub fn assert_verdict(rows: &[Row]) {
    let false_found: Vec<&str> = rows
        .iter()
        .filter(|r| r.verdict.found && r.wrong())
        .map(|r| r.name)
        .collect();
    assert!(
        false_found.is_empty(),
        "poses more than 20 mm or 10° off reported found: {false_found:?}"
    );
}
