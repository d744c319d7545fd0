//! What the demo saw: the truth and the poses of each object, the figures of the live
//! status and the summary, the trajectory plot, and for a scenario the success against
//! the truth.

use std::collections::BTreeMap;

use nalgebra::{Quaternion, UnitQuaternion};

use crate::capture::scenario::{reacquisitions, InView, Judged, Return, GOOD, SCORED_SHARE, WRONG};
use crate::cli::report::plot::{self, Panel, Series, PALETTE};
use crate::cli::report::stats::Samples;
use crate::transport::messages::{PoseMsg, PoseSet, Status};

/// A labelled line of a plot panel.
type Line = (String, Vec<(f64, f64)>);

/// What the demo saw of each object, in the estimator's order; for a scenario, each
/// frame's share of the card in view.
pub struct Run {
    tracks: Vec<(String, Record)>,
    visible: Option<Vec<InView>>,
}

impl Run {
    pub fn new(names: &[String], visible: Option<Vec<InView>>) -> Self {
        Self {
            tracks: names.iter().map(|n| (n.clone(), Record::default())).collect(),
            visible,
        }
    }

    /// A scenario's frames so far judged against the truth (the first object's).
    fn judged(&self) -> Option<Judgement> {
        let visible = self.visible.as_deref().filter(|v| !v.is_empty())?;
        let record = &self.tracks[0].1;
        let poses: BTreeMap<u64, &PoseMsg> = record.poses.iter().map(|(p, _)| (p.frame_id, p)).collect();
        let last = *poses.keys().next_back()?;
        let frames: Vec<(f64, Judged)> = (record.truth.range(..=last))
            .map(|(id, truth)| {
                let visible = visible[(*id % visible.len() as u64) as usize];
                let judged = match poses.get(id) {
                    Some(p) => judge(p, truth, visible),
                    None => Judged::without_pose(visible),
                };
                (truth.capture_time_ns as f64 * 1e-9, judged)
            })
            .collect();
        Some(Judgement::of(&frames))
    }

    /// Files each object's truth by name (a lone truth goes to a lone object).
    pub fn truth(&mut self, set: &PoseSet) {
        let lone = self.tracks.len() == 1 && set.count == 1;
        for (name, record) in &mut self.tracks {
            if let Some(t) = set.get(name).or(if lone { set.first() } else { None }) {
                record.truth.insert(t.frame_id, *t);
            }
        }
    }

    /// Files each object's pose, received at `now`.
    pub fn poses(&mut self, set: &PoseSet, now: u64) {
        for (name, record) in &mut self.tracks {
            if let Some(p) = set.get(name) {
                record.poses.push((*p, now));
            }
        }
    }

    /// The status line: the first object's figures, then the others' errors.
    pub fn status(&self, elapsed: f64) -> String {
        let mut line = self.tracks[0].1.status(elapsed);
        if let Some(j) = self.judged() {
            line += &format!(" | success {:.0} %", j.success());
        }
        if self.tracks.len() > 1 {
            for (name, record) in &self.tracks {
                let errors = Samples::new(record.tracked().map(|(p, t, _)| position_error(p, t)));
                line += &format!(" | {name} {} p95 {:.1} mm", record.state(), errors.percentile(95.0));
            }
        }
        line
    }

    /// x, y, z against time: each object's truth and estimate, one panel per axis.
    pub fn plot(&self) -> Result<image::RgbImage, plot::PlotError> {
        let t0 = (self.tracks.iter())
            .filter_map(|(_, r)| r.truth.values().next().map(|t| t.capture_time_ns))
            .min()
            .unwrap_or(0);
        let time = |ns: u64| ns.saturating_sub(t0) as f64 * 1e-9;
        // Per axis, per object: (label, points) of the truth, then of the estimate.
        let one = self.tracks.len() == 1;
        let data: Vec<Vec<Line>> = (0..3)
            .map(|i| {
                let mut lines = Vec::new();
                for (name, r) in &self.tracks {
                    let label = |what: &str| {
                        if one {
                            what.to_string()
                        } else {
                            format!("{name} {what}")
                        }
                    };
                    let truth = r.truth.values().map(|t| (time(t.capture_time_ns), t.position_mm[i]));
                    let estimate = r.poses.iter().map(|(p, _)| (time(p.capture_time_ns), p.position_mm[i]));
                    lines.push((label("truth"), truth.collect()));
                    lines.push((label("estimate"), estimate.collect()));
                }
                lines
            })
            .collect();
        let titles = ["x (hand frame)", "y (hand frame)", "z (hand frame)"];
        let panels: Vec<Panel> = (data.iter().zip(titles))
            .map(|(lines, title)| Panel {
                title,
                x_label: "time [s]",
                y_label: "position [mm]",
                series: (lines.iter().enumerate())
                    .map(|(k, (label, points))| Series {
                        label,
                        points,
                        color: PALETTE[k % PALETTE.len()],
                    })
                    .collect(),
                ..Default::default()
            })
            .collect();
        plot::panels(&panels, 1200, 900)
    }

    /// The summary, one block per object; for a scenario, the success against the truth.
    pub fn summary(&self) -> String {
        if self.tracks.len() == 1 {
            let judged = self.judged().map(|j| format!("\n{}", j.summary())).unwrap_or_default();
            return self.tracks[0].1.summary() + &judged;
        }
        let blocks: Vec<String> = self
            .tracks
            .iter()
            .map(|(name, record)| format!("{name}:\n{}", record.summary()))
            .collect();
        blocks.join("\n")
    }
}

/// What the demo saw of one object: the truth of every frame and every pose with the
/// time it arrived.
#[derive(Default)]
struct Record {
    truth: BTreeMap<u64, PoseMsg>,
    poses: Vec<(PoseMsg, u64)>,
}

/// A scenario's poses against the truth, counted as the tracking sequences count them.
struct Judgement {
    /// Frames with enough of the card in view, and those of them with a good pose.
    scored: usize,
    good: usize,
    /// `tracking` poses too far off, and while the card was out of view.
    wrong: usize,
    out_of_view: usize,
    /// For each return of the card into view, the seconds to the first good pose.
    back: Vec<Return>,
}

impl Judgement {
    /// The judgement of `frames`: each frame's capture time, seconds, and its judged pose.
    fn of(frames: &[(f64, Judged)]) -> Self {
        let mut j = Judgement {
            scored: 0,
            good: 0,
            wrong: 0,
            out_of_view: 0,
            back: reacquisitions(frames),
        };
        for (_, f) in frames {
            j.scored += f.scored() as usize;
            j.good += (f.scored() && f.good()) as usize;
            j.wrong += f.wrong() as usize;
            j.out_of_view += f.tracking_out_of_view() as usize;
        }
        j
    }

    /// The success rate, %.
    fn success(&self) -> f64 {
        100.0 * self.good as f64 / self.scored.max(1) as f64
    }

    fn summary(&self) -> String {
        let [mm, size, deg] = GOOD;
        let [wrong_mm, wrong_deg] = WRONG;
        let back: Vec<String> = self.back.iter().map(|r| r.to_string()).collect();
        let back = if back.is_empty() {
            String::new()
        } else {
            format!("\nback in view → good tracking pose after: {}", back.join(", "))
        };
        format!(
            "success: {:.1} % ({} of {} frames with ≥ {:.0} % of the card in view got a tracking pose within {mm} mm, {deg}° and {:.0} %)\n\
             tracking poses more than {wrong_mm} mm or {wrong_deg}° off: {};  tracking while the card was out of view: {}{back}",
            self.success(),
            self.good,
            self.scored,
            100.0 * SCORED_SHARE,
            100.0 * size,
            self.wrong,
            self.out_of_view
        )
    }
}

/// Judges a pose against the truth of its frame.
fn judge(p: &PoseMsg, t: &PoseMsg, visible: InView) -> Judged {
    let rotation = |q: [f64; 4]| UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]));
    let rel = |k: usize| (p.size_mm[k] - t.size_mm[k]).abs() / t.size_mm[k];
    Judged {
        in_view: visible,
        tracking: p.status == Status::Tracking as u32,
        errors: [
            position_error(p, t),
            rel(0).max(rel(1)),
            rotation(p.orientation_wxyz)
                .angle_to(&rotation(t.orientation_wxyz))
                .to_degrees(),
        ],
    }
}

/// Position error of a pose against the truth of its frame, mm.
fn position_error(p: &PoseMsg, t: &PoseMsg) -> f64 {
    (0..3)
        .map(|i| (p.position_mm[i] - t.position_mm[i]).powi(2))
        .sum::<f64>()
        .sqrt()
}

impl Record {
    /// The index of the first tracking pose: the end of the first acquisition.
    fn acquired(&self) -> usize {
        let tracking = |(p, _): &&(PoseMsg, u64)| p.status == Status::Tracking as u32;
        self.poses.iter().position(|p| tracking(&p)).unwrap_or(self.poses.len())
    }

    /// Tracking poses after the first (the acquisition), with their truth.
    fn tracked(&self) -> impl Iterator<Item = (&PoseMsg, &PoseMsg, u64)> {
        self.poses
            .iter()
            .skip(self.acquired() + 1)
            .filter(|(p, _)| p.status == Status::Tracking as u32)
            .filter_map(|(p, at)| Some((p, self.truth.get(&p.frame_id)?, *at)))
    }

    /// Frames the estimator skipped while tracking, and the frames from each tracking
    /// pose to the next. The frames after a search of the whole frame (an acquisition or
    /// the relocation after it: more generations than the median pose) are left out, as
    /// `photopose latency` does: it takes many frame periods.
    fn dropped(&self) -> (u64, u64) {
        let median = Samples::new(self.poses.iter().map(|(p, _)| p.generations as f64)).median();
        let (mut dropped, mut span) = (0, 0);
        for w in self.poses.windows(2) {
            let (a, b) = (&w[0].0, &w[1].0);
            if a.generations as f64 > median {
                continue;
            }
            let gap = b.frame_id.saturating_sub(a.frame_id + 1);
            dropped += gap;
            span += gap + 1;
        }
        (dropped, span)
    }

    /// Frames that went by during the acquisition.
    fn acquisition_frames(&self) -> u64 {
        match (self.truth.keys().next(), self.poses.get(self.acquired() + 1)) {
            (Some(&a), Some((b, _))) => b.frame_id.saturating_sub(a + 1),
            _ => 0,
        }
    }

    /// The camera's frame rate so far.
    fn fps(&self) -> f64 {
        match (self.truth.values().next(), self.truth.values().next_back()) {
            (Some(a), Some(b)) if b.capture_time_ns > a.capture_time_ns => {
                (self.truth.len() - 1) as f64 / ((b.capture_time_ns - a.capture_time_ns) as f64 * 1e-9)
            }
            _ => 0.0,
        }
    }

    /// One line of figures so far, `elapsed` seconds in.
    fn status(&self, elapsed: f64) -> String {
        let errors = Samples::new(self.tracked().map(|(p, t, _)| position_error(p, t)));
        let latency = Samples::new(
            self.poses
                .iter()
                .map(|(p, _)| (p.publish_time_ns.saturating_sub(p.capture_time_ns)) as f64 * 1e-6),
        );
        let state = self.state();
        format!(
            "{elapsed:5.1} s | frames {:5} ({:4.1} fps) | poses {:5} dropped {:3} | {state} | error {:5.1} mm (p95 {:5.1}) | capture→pose p50 {:5.1} ms p99 {:5.1} ms",
            self.truth.len(),
            self.fps(),
            self.poses.len(),
            self.dropped().0,
            errors.median(),
            errors.percentile(95.0),
            latency.median(),
            latency.percentile(99.0)
        )
    }

    /// The newest pose's status, or `acquiring`.
    fn state(&self) -> String {
        self.poses
            .last()
            .map(|(p, _)| crate::client::status_name(p.status))
            .unwrap_or_else(|| "acquiring".into())
    }

    /// The report printed at the end.
    fn summary(&self) -> String {
        let errors = Samples::new(self.tracked().map(|(p, t, _)| position_error(p, t)));
        let latency = Samples::new(
            self.poses
                .iter()
                .skip(1)
                .map(|(p, _)| p.publish_time_ns.saturating_sub(p.capture_time_ns) as f64 * 1e-6),
        );
        let end_to_end = Samples::new(
            self.poses
                .iter()
                .skip(1)
                .map(|(p, at)| at.saturating_sub(p.capture_time_ns) as f64 * 1e-6),
        );
        let tracking = self
            .poses
            .iter()
            .filter(|(p, _)| p.status == Status::Tracking as u32)
            .count();
        // From the first frame to the first tracking pose (an object acquired in the
        // background is published as `searching` meanwhile).
        let first_frame = self.truth.values().next().map(|t| t.capture_time_ns);
        let acquisition = match (first_frame, self.poses.get(self.acquired())) {
            (Some(t0), Some((p, _))) => p.publish_time_ns.saturating_sub(t0) as f64 * 1e-9,
            _ => f64::NAN,
        };
        let (dropped, span) = self.dropped();
        format!(
            "frames {}  poses {} ({tracking} tracking)  dropped while tracking {dropped} of {span} ({:.2} %)\n\
             acquisition {acquisition:.2} s (first frame → first tracking pose; {} frames went by)\n\
             position error (tracking): mean {:.1} mm  p95 {:.1} mm  max {:.1} mm\n\
             latency capture→pose published: p50 {:.1} ms  p99 {:.1} ms;  capture→pose received: p50 {:.1} ms  p99 {:.1} ms",
            self.truth.len(),
            self.poses.len(),
            100.0 * dropped as f64 / span.max(1) as f64,
            self.acquisition_frames(),
            errors.mean(),
            errors.percentile(95.0),
            errors.max(),
            latency.median(),
            latency.percentile(99.0),
            end_to_end.median(),
            end_to_end.percentile(99.0)
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transport::messages::ObjectName;

    fn pose(frame_id: u64, x: f64, turn_deg: f64, length: f64, status: Status) -> PoseMsg {
        let half = 0.5 * turn_deg.to_radians();
        PoseMsg {
            frame_id,
            position_mm: [x, 0.0, 700.0],
            orientation_wxyz: [half.cos(), 0.0, 0.0, half.sin()],
            size_mm: [length, 80.0],
            status: status as u32,
            ..Default::default()
        }
    }

    #[test]
    fn a_scenario_run_counts_success_against_the_truth_of_each_frame() {
        let name = ObjectName::from_stem("card");
        let seen = |left, both_eyes| InView { left, both_eyes };
        let visible = vec![seen(1.0, 1.0), seen(1.0, 0.7), seen(0.5, 0.0), seen(0.0, 0.0)];
        let mut run = Run::new(&["card".into()], Some(visible));
        for id in 0..6 {
            run.truth(&PoseSet::single(&name, pose(id, 0.0, 0.0, 100.0, Status::Tracking)));
        }
        let estimates = [
            pose(0, 19.0, 9.0, 109.0, Status::Tracking), // good
            pose(1, 0.0, 0.0, 100.0, Status::Searching), // right but not tracking
            pose(2, 0.0, 0.0, 100.0, Status::Tracking),  // half in view: not scored
            pose(3, 0.0, 0.0, 100.0, Status::Tracking),  // out of view
            pose(4, 0.0, 21.0, 100.0, Status::Tracking), // frame 4 is frame 0 again: wrong
        ];
        for p in estimates {
            run.poses(&PoseSet::single(&name, p), 0);
        }
        let j = run.judged().unwrap();
        // Frames 0, 1 and 4 are scored (frame 5 has no pose yet); only frame 0 is good.
        assert_eq!((j.scored, j.good, j.wrong, j.out_of_view), (3, 1, 1, 1));
        // The card came back into view on frame 4, and no good pose followed.
        assert_eq!(j.back.len(), 1);
        assert!(j.back[0].left.is_infinite(), "{:?}", j.back);
        assert!(run.status(1.0).ends_with("| success 33 %"), "{}", run.status(1.0));
        assert!(
            run.summary().contains("success: 33.3 % (1 of 3 frames"),
            "{}",
            run.summary()
        );
        assert!(
            run.summary().contains("back in view → good tracking pose after: never"),
            "{}",
            run.summary()
        );
    }
}
