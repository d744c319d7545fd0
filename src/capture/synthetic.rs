//! `synthetic[:SCENE.toml]`: the synthetic camera. The scene's card (and the cards of
//! further scene files, `capture --card`) move along scripted [`Trajectory`] loops at
//! the camera's rate and resolution; each frame is rendered straight into the caller's
//! buffer and comes with every card's ground truth.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use super::{FrameBuf, FrameInfo, FrameSource, Geometry, SourceError, Truth, Written};
use crate::config::Config;
use crate::render::{Renderer, Scene, SceneSpec};
use crate::transport::messages::{monotonic_ns, ObjectName, MAX_OBJECTS};
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

/// One card of the synthetic camera: its scene (the first card's wall), the renderer
/// of that scene, its motion and its name.
struct Moving {
    name: ObjectName,
    scene: Scene,
    renderer: Renderer,
    trajectory: Trajectory,
}

/// Each further card's loop is this much slower than the previous one's, so the cards
/// move independently.
const FURTHER_CARD_SLOWER: f64 = 0.77;

/// The synthetic camera as a frame source.
pub struct SyntheticSource {
    scene_path: String,
    /// The first card (its scene holds the wall) and any further ones.
    cards: Vec<Moving>,
    geometry: Geometry,
    fps: f64,
    start: Instant,
    /// Frames rendered so far; frame `n` shows the cards at `n / fps` seconds.
    frames: u64,
}

impl SyntheticSource {
    /// The scene file's card moving at up to `speed_mm_s`, `fps` frames per second.
    pub fn open(scene_path: &Path, config: &Config, fps: f64, speed_mm_s: f64) -> Result<Self, SourceError> {
        Self::with_cards(scene_path, &[], config, fps, speed_mm_s)
    }

    /// [`SyntheticSource::open`] with the cards of further scene files in front of the
    /// first one's wall (their photo, box, pose and size; their walls are not used),
    /// each on a loop of its own. Cards must not overlap in the images: each is
    /// rendered over the wall alone.
    pub fn with_cards(
        scene_path: &Path,
        more: &[PathBuf],
        config: &Config,
        fps: f64,
        speed_mm_s: f64,
    ) -> Result<Self, SourceError> {
        let setup = |e: &dyn std::fmt::Display| SourceError::Setup(e.to_string());
        let spec = SceneSpec::load(scene_path).map_err(|e| setup(&e))?;
        let rig = config.calibration.rig(spec.resolution).map_err(|e| setup(&e))?;
        let first = spec.build(&config.left_from_hand).map_err(|e| setup(&e))?;
        let mut cards = Vec::new();
        for (k, path) in std::iter::once(scene_path)
            .chain(more.iter().map(PathBuf::as_path))
            .enumerate()
        {
            let card_spec = SceneSpec::load(path).map_err(|e| setup(&e))?;
            let mut scene = first.clone();
            if k > 0 {
                scene.card = card_spec.build(&config.left_from_hand).map_err(|e| setup(&e))?.card;
                scene.occluder = None;
            }
            let speed = speed_mm_s * FURTHER_CARD_SLOWER.powi(k as i32);
            cards.push(Moving {
                name: card_name(&card_spec.photo, k, &cards),
                renderer: Renderer::new(&rig, &config.left_from_hand, &scene),
                trajectory: Trajectory::with_peak_speed(scene.card.hand_from_model, speed),
                scene,
            });
        }
        if cards.len() > MAX_OBJECTS {
            return Err(SourceError::Setup(format!(
                "{} cards: a pose set carries at most {MAX_OBJECTS}",
                cards.len()
            )));
        }
        Ok(Self {
            scene_path: scene_path.display().to_string(),
            cards,
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

    /// The first card's motion.
    pub fn trajectory(&self) -> &Trajectory {
        &self.cards[0].trajectory
    }
}

/// A card's name: its photo's file stem, with `_2`, `_3` … for repeats of a photo.
fn card_name(photo: &Path, index: usize, before: &[Moving]) -> ObjectName {
    let stem = photo.file_stem().map(|s| s.to_string_lossy()).unwrap_or_default();
    let name = ObjectName::from_stem(&stem);
    if before.iter().any(|c| c.name == name) {
        return ObjectName::from_stem(&format!("{}_{}", &stem[..stem.len().min(28)], index + 1));
    }
    name
}

impl FrameSource for SyntheticSource {
    fn geometry(&self) -> Geometry {
        self.geometry
    }

    fn describe(&self) -> String {
        let loops: Vec<String> = self
            .cards
            .iter()
            .map(|c| format!("{} on a loop of {:.1} s", c.name, c.trajectory.period_s))
            .collect();
        format!(
            "synthetic camera on {} at {} fps, {}x{} per eye: {}",
            self.scene_path,
            self.fps,
            self.geometry.width,
            self.geometry.height,
            loops.join(", ")
        )
    }

    fn objects(&self) -> Vec<ObjectName> {
        self.cards.iter().map(|c| c.name.clone()).collect()
    }

    fn next_due(&mut self) -> Option<Instant> {
        if self.frames == 0 {
            self.start = Instant::now();
        }
        Some(self.start + Duration::from_secs_f64(self.frames as f64 / self.fps))
    }

    fn write_frame<'a>(&mut self, buf: FrameBuf<'a>) -> Result<Option<(FrameInfo, Written<'a>)>, SourceError> {
        let t = self.frames as f64 / self.fps;
        // The empty scene is copied in whole, then each card is rendered over it: every
        // byte of the (possibly uninitialised) buffer is written once, none zeroed.
        let mut frame = buf.copy_from(self.cards[0].renderer.background())?;
        let mut truth = [None; MAX_OBJECTS];
        for (card, slot) in self.cards.iter_mut().zip(&mut truth) {
            let pose = card.trajectory.pose_at(t);
            card.scene.card.hand_from_model = pose;
            card.renderer.render_over(&card.scene, frame.bytes_mut());
            *slot = Some(Truth {
                hand_from_model: pose,
                size_mm: card.scene.card.size_mm,
            });
        }
        self.frames += 1;
        let info = FrameInfo {
            capture_time_ns: monotonic_ns(),
            truth,
            frame_id: None,
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
