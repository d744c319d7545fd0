//! `photopose estimate --rerun`: a one-shot search generation by generation. The
//! frame's pyramid levels are logged once; then, on the `generation` time line, the best
//! individual's outline on the full-resolution image and on the level being searched,
//! its box in 3D, and its fitness, level, position and size.

use anyhow::Result;
use rerun::{LineStrips2D, RecordingStream};

use crate::camera::{Intrinsics, StereoRig};
use crate::estimator::ga::observe::Generation;
use crate::estimator::model::PhotoModel;
use crate::estimator::pose::PoseSize;
use crate::transport::messages::{PoseMsg, Status};
use crate::viewer::outline::{card_outline, status_colour};
use crate::viewer::scene::{self, Drawing, Kind};
use crate::viewer::thumbnail;
use crate::vision::frame::{coarse_levels, StereoImages};
use crate::vision::PixelFormat;

/// The time line of a one-shot search.
pub const GENERATION_TIMELINE: &str = "generation";
/// One colour per pyramid level, finest first.
const LEVEL_COLOURS: [[u8; 3]; 4] = [[40, 220, 60], [255, 220, 0], [255, 120, 0], [230, 40, 230]];

/// Logs one search to a recording.
pub struct SearchLog<'a> {
    rec: &'a RecordingStream,
    model: &'a PhotoModel,
    left_from_hand: &'a nalgebra::Isometry3<f64>,
    /// The rig of each pyramid level, level 0 at full resolution.
    rigs: Vec<StereoRig>,
    /// The camera of the logged full-resolution image (shrunk when wider than 1280).
    camera: Option<Intrinsics>,
}

impl<'a> SearchLog<'a> {
    /// Logs the camera and the left image of every level of `images`' pyramid, whose
    /// rigs are `rigs` (static: they do not change during the search).
    pub fn new(
        rec: &'a RecordingStream,
        model: &'a PhotoModel,
        left_from_hand: &'a nalgebra::Isometry3<f64>,
        images: &StereoImages,
        rigs: Vec<StereoRig>,
    ) -> Result<Self> {
        let step = thumbnail::factor(images.left.width() as usize, MAX_WIDTH, PixelFormat::Rgb8);
        let camera = rigs.first().map(|r| r.left.scaled(1.0 / step as f64));
        let full = thumbnail::shrink_rgb(&images.left, step);
        if let Some(c) = &camera {
            scene::log_camera(rec, left_from_hand, c, full.dimensions())?;
        }
        crate::viewer::layout::search(rec, rigs.len())?;
        rec.log_static(scene::IMAGE, &scene::jpeg(&full, 85)?)?;
        for (l, level) in coarse_levels(images, rigs.len()).iter().enumerate() {
            rec.log_static(format!("pyramid/level_{}", l + 1), &scene::jpeg(&level.left, 85)?)?;
        }
        Ok(Self {
            rec,
            model,
            left_from_hand,
            rigs,
            camera,
        })
    }

    /// The best individual of one generation (an [`crate::estimator::ga::observe::Observer`]).
    pub fn generation(&self, g: &Generation) -> Result<()> {
        self.rec.set_time_sequence(GENERATION_TIMELINE, g.generation as i64);
        let colour = LEVEL_COLOURS[g.level.min(LEVEL_COLOURS.len() - 1)];
        self.best(&g.best, g.fitness.f, g.generation, colour)?;
        scene::scalar(self.rec, "ga/fitness", g.fitness.f)?;
        scene::scalar(self.rec, "ga/score", g.fitness.score)?;
        scene::scalar(self.rec, "ga/level", g.level as f64)?;
        if let Some(rig) = self.rigs.get(g.level).filter(|_| g.level > 0) {
            let size = g.best.size_mm(self.model.l_p, self.model.b_p);
            let lines = card_outline(&g.best.hand_from_model(), size, 0.0, self.left_from_hand, &rig.left);
            self.rec.log(
                format!("pyramid/level_{}/best", g.level),
                &LineStrips2D::new(lines).with_colors([rerun::Color::from_rgb(colour[0], colour[1], colour[2])]),
            )?;
        }
        Ok(())
    }

    /// The search's result after the refinement, at generation `generations`.
    pub fn result(&self, best: &PoseSize, fitness: f64, generations: usize) -> Result<()> {
        self.rec.set_time_sequence(GENERATION_TIMELINE, generations as i64);
        self.best(best, fitness, generations, status_colour(Status::Tracking as u32))
    }

    /// `best` as the estimate: box, outline on the full image, position and size.
    fn best(&self, best: &PoseSize, fitness: f64, generation: usize, colour: [u8; 3]) -> Result<()> {
        let pose = PoseMsg {
            frame_id: generation as u64,
            position_mm: [best.position.x, best.position.y, best.position.z],
            orientation_wxyz: best.orientation_wxyz(),
            size_mm: best.size_mm(self.model.l_p, self.model.b_p),
            fitness,
            generations: generation as u32,
            ..Default::default()
        };
        let drawing = Drawing {
            colour,
            strip_per_length: self.model.outer_width_px / self.model.l_p,
            left_from_hand: self.left_from_hand,
            camera: self.camera,
        };
        scene::log_pose(self.rec, Kind::Estimate, &pose, &drawing)?;
        scene::log_position(self.rec, Kind::Estimate, &pose)?;
        scene::scalar(self.rec, "series/size/L", pose.size_mm[0])?;
        scene::scalar(self.rec, "series/size/B", pose.size_mm[1])?;
        Ok(())
    }
}

/// The widest full-resolution image logged, pixels.
const MAX_WIDTH: usize = 1280;
