//! Frame sources for the capture process. `synthetic[:SCENE.toml]` renders the scene's
//! card moving along a scripted trajectory and knows each frame's ground truth.

use std::path::PathBuf;

use anyhow::{bail, Result};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use crate::messages::PoseMsg;
use crate::pose::PoseSize;

/// Where frames come from.
#[derive(Debug, Clone, PartialEq)]
pub enum Source {
    /// The synthetic camera rendering a scene file.
    Synthetic(PathBuf),
}

/// Scene of `synthetic` without a file name.
pub const DEFAULT_SCENE: &str = "config/scenes/rocket.toml";

impl Source {
    /// Parses `synthetic`, `synthetic:SCENE.toml`.
    pub fn parse(s: &str) -> Result<Self> {
        match s.split_once(':') {
            None if s == "synthetic" => Ok(Source::Synthetic(PathBuf::from(DEFAULT_SCENE))),
            Some(("synthetic", scene)) if !scene.is_empty() => Ok(Source::Synthetic(PathBuf::from(scene))),
            _ => bail!("unknown source {s:?}: use synthetic[:SCENE.toml]"),
        }
    }
}

/// A smooth closed loop around the scene's pose, in the hand frame: a Lissajous figure
/// (x at the loop frequency, y at twice it, z at it with a phase) and a gentle turn
/// about the card normal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Trajectory {
    pub centre: Isometry3<f64>,
    /// Half-extent of the loop along hand x, y, z, mm.
    pub amplitude_mm: [f64; 3],
    /// Peak turn about the card normal, degrees.
    pub turn_deg: f64,
    /// Loop period, s.
    pub period_s: f64,
}

impl Trajectory {
    /// A loop of about ±60 × ±30 × ±40 mm whose peak speed is `speed_mm_s`.
    pub fn with_peak_speed(centre: Isometry3<f64>, speed_mm_s: f64) -> Self {
        let mut t = Trajectory {
            centre,
            amplitude_mm: [60.0, 30.0, 40.0],
            turn_deg: 10.0,
            period_s: 1.0,
        };
        let peak = t.peak_speed();
        t.period_s = if speed_mm_s > 0.0 {
            peak / speed_mm_s
        } else {
            f64::INFINITY
        };
        t
    }

    fn omega(&self) -> f64 {
        std::f64::consts::TAU / self.period_s
    }

    /// The card pose in the hand frame at time `t` (s).
    pub fn pose_at(&self, t: f64) -> Isometry3<f64> {
        let w = self.omega() * t;
        let [ax, ay, az] = self.amplitude_mm;
        let offset = Vector3::new(
            ax * w.sin(),
            ay * (2.0 * w).sin(),
            az * (w + 1.0).sin() - az * 1f64.sin(),
        );
        let turn = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), self.turn_deg.to_radians() * w.sin());
        Isometry3::from_parts(
            Translation3::from(self.centre.translation.vector + offset),
            self.centre.rotation * turn,
        )
    }

    /// Largest speed along the loop, mm/s (sampled).
    pub fn peak_speed(&self) -> f64 {
        let dt = self.period_s / 2000.0;
        (0..2000)
            .map(|i| {
                let t = i as f64 * dt;
                (self.pose_at(t + dt).translation.vector - self.pose_at(t).translation.vector).norm() / dt
            })
            .fold(0.0, f64::max)
    }
}

/// A pose message for a model at `hand_from_model` of `size_mm`.
pub fn pose_msg(frame_id: u64, capture_time_ns: u64, hand_from_model: &Isometry3<f64>, size_mm: [f64; 2]) -> PoseMsg {
    let p = PoseSize::from_pose(hand_from_model, size_mm, size_mm[0], size_mm[1]);
    PoseMsg {
        frame_id,
        capture_time_ns,
        publish_time_ns: 0,
        position_mm: p.position.into(),
        orientation_wxyz: p.orientation_wxyz(),
        size_mm,
        fitness: 0.0,
        generations: 0,
        status: crate::messages::status::TRACKING,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sources_parse_or_explain() {
        assert_eq!(
            Source::parse("synthetic").unwrap(),
            Source::Synthetic(PathBuf::from(DEFAULT_SCENE))
        );
        assert_eq!(
            Source::parse("synthetic:a/b.toml").unwrap(),
            Source::Synthetic(PathBuf::from("a/b.toml"))
        );
        let e = Source::parse("webcam").unwrap_err().to_string();
        assert!(e.contains("webcam") && e.contains("synthetic"), "{e}");
    }

    #[test]
    fn trajectory_loops_at_the_requested_peak_speed() {
        let centre = Isometry3::translation(0.0, 0.0, 700.0);
        let t = Trajectory::with_peak_speed(centre, 150.0);
        assert!((t.peak_speed() - 150.0).abs() < 1.0, "{}", t.peak_speed());
        let (a, b) = (t.pose_at(0.0), t.pose_at(t.period_s));
        assert!((a.translation.vector - b.translation.vector).norm() < 1e-6);
        assert!(
            (a.translation.vector - centre.translation.vector).norm() < 1e-9,
            "starts at the scene pose"
        );
    }
}
