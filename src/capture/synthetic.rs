//! `synthetic[:SCENE.toml]`: the synthetic camera. The scene's card moves along a
//! scripted [`Trajectory`] at the camera's rate and resolution; each frame is rendered
//! straight into the caller's buffer and comes with its ground truth.

use std::path::Path;
use std::time::{Duration, Instant};

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use super::{FrameBuf, FrameInfo, FrameSource, Geometry, SourceError, Truth, Written};
use crate::config::Config;
use crate::render::{Renderer, Scene, SceneSpec};
use crate::transport::messages::monotonic_ns;
use crate::vision::PixelFormat;

/// A smooth closed loop around the scene's pose, in the hand frame: a Lissajous figure
/// (x at the loop frequency, y at twice it, z at it with a phase) and a gentle turn
/// about the card normal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Trajectory {
    /// The loop's centre pose of the card (`hand_from_model`, mm).
    pub centre: Isometry3<f64>,
    /// Half-extent of the loop along hand x, y, z, mm.
    pub amplitude_mm: [f64; 3],
    /// Peak turn about the card normal, degrees.
    pub turn_deg: f64,
    /// Loop period, s.
    pub period_s: f64,
}

impl Trajectory {
    /// A loop of about ±60 × ±30 × ±40 mm whose peak speed is `speed_mm_s` (0: still).
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

/// The synthetic camera as a frame source.
pub struct SyntheticSource {
    scene_path: String,
    scene: Scene,
    renderer: Renderer,
    trajectory: Trajectory,
    geometry: Geometry,
    fps: f64,
    start: Instant,
    /// Frames rendered so far; frame `n` shows the card at `n / fps` seconds.
    frames: u64,
}

impl SyntheticSource {
    /// The scene file's card moving at up to `speed_mm_s`, `fps` frames per second.
    pub fn open(scene_path: &Path, config: &Config, fps: f64, speed_mm_s: f64) -> Result<Self, SourceError> {
        let spec = SceneSpec::load(scene_path).map_err(|e| SourceError::Setup(e.to_string()))?;
        let rig = config
            .calibration
            .rig(spec.resolution)
            .map_err(|e| SourceError::Setup(e.to_string()))?;
        let scene = spec
            .build(&config.left_from_hand)
            .map_err(|e| SourceError::Setup(e.to_string()))?;
        let trajectory = Trajectory::with_peak_speed(scene.card.hand_from_model, speed_mm_s);
        let renderer = Renderer::new(&rig, &config.left_from_hand, &scene);
        Ok(Self {
            scene_path: scene_path.display().to_string(),
            scene,
            renderer,
            trajectory,
            geometry: Geometry {
                width: rig.width,
                height: rig.height,
                format: PixelFormat::Rgb8,
            },
            fps,
            start: Instant::now(),
            frames: 0,
        })
    }

    /// The card's motion.
    pub fn trajectory(&self) -> &Trajectory {
        &self.trajectory
    }
}

impl FrameSource for SyntheticSource {
    fn geometry(&self) -> Geometry {
        self.geometry
    }

    fn describe(&self) -> String {
        format!(
            "synthetic camera on {} at {} fps, {}x{} per eye, card loop of {:.1} s",
            self.scene_path, self.fps, self.geometry.width, self.geometry.height, self.trajectory.period_s
        )
    }

    fn next_due(&mut self) -> Option<Instant> {
        if self.frames == 0 {
            self.start = Instant::now();
        }
        Some(self.start + Duration::from_secs_f64(self.frames as f64 / self.fps))
    }

    fn write_frame<'a>(&mut self, buf: FrameBuf<'a>) -> Result<Option<(FrameInfo, Written<'a>)>, SourceError> {
        let pose = self.trajectory.pose_at(self.frames as f64 / self.fps);
        self.scene.card.hand_from_model = pose;
        // The empty scene is copied in whole, then the card is rendered over it: every
        // byte of the (possibly uninitialised) buffer is written once, none zeroed.
        let mut frame = buf.copy_from(self.renderer.background())?;
        self.renderer.render_over(&self.scene, frame.bytes_mut());
        self.frames += 1;
        let info = FrameInfo {
            capture_time_ns: monotonic_ns(),
            truth: Some(Truth {
                hand_from_model: pose,
                size_mm: self.scene.card.size_mm,
            }),
        };
        Ok(Some((info, frame)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
        let still = Trajectory::with_peak_speed(centre, 0.0);
        assert_eq!(still.pose_at(3.0), centre);
    }
}
