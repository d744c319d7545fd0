//! Tracking across frames, as in the authors' real-time multi-step GA: the population
//! of the previous frame is moved by the predicted motion, re-scored on the new frame
//! and evolved for a few generations; the best individual is the frame's pose. When
//! the fitness stays low the search widens (immigrants), and after a while the object
//! is acquired afresh with the one-shot robust search.

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use nalgebra::Isometry3;

use crate::calibration::CalibrationError;
use crate::camera::StereoRig;
use crate::config::{Config, GaSettings, Mode, RobustSettings, TrackingSettings};
use crate::estimate::{scorer_for, Prepared};
use crate::fitness::{Fitness, PointSet, Scorer};
use crate::frame::Region;
use crate::ga::robust::{mutate, Population};
use crate::ga::{Bounds, Genes, Problem, GENES};
use crate::lookup::{LevelLookup, SbsBytes};
use crate::messages::{status, PoseMsg};
use crate::model::PhotoModel;
use crate::pose::PoseSize;

/// The result for one frame.
#[derive(Debug, Clone, Copy)]
pub struct Estimate {
    pub best: PoseSize,
    /// Fitness of `best` at full resolution.
    pub fitness: Fitness,
    /// Generations run on this frame.
    pub generations: u32,
    /// One of [`crate::messages::status`].
    pub status: u32,
}

/// A GA population that lives from frame to frame.
pub struct Tracker {
    settings: TrackingSettings,
    ga: GaSettings,
    robust: RobustSettings,
    pop: Population,
    order: Vec<usize>,
    rng: StdRng,
    /// Frames in a row below `min_fitness`.
    searching: usize,
    /// Best genes of the last frame and their change per frame (constant velocity).
    last_best: Option<Genes>,
    velocity: Genes,
    frames: u64,
}

impl Tracker {
    pub fn new(config: &Config, seed: u64) -> Self {
        let n = config.tracking.population;
        Self {
            settings: config.tracking.clone(),
            ga: config.ga.clone(),
            robust: config.robust.clone(),
            pop: Population::new(Vec::with_capacity(n)),
            order: Vec::with_capacity(n),
            rng: StdRng::seed_from_u64(seed),
            searching: 0,
            last_best: None,
            velocity: [0.0; GENES],
            frames: 0,
        }
    }

    /// True until the first acquisition, and after the object was lost.
    pub fn needs_acquisition(&self) -> bool {
        self.pop.genes.is_empty() || self.searching > self.settings.lost_after_frames
    }

    /// The genes expected on the next frame (last best moved by the estimated velocity);
    /// `None` while the object has to be acquired.
    pub fn prediction(&self) -> Option<Genes> {
        if self.needs_acquisition() {
            return None;
        }
        self.last_best
            .map(|b| std::array::from_fn(|i| (b[i] + self.velocity[i]).clamp(0.0, 1.0)))
    }

    /// Processes one frame.
    pub fn step(&mut self, problem: &Problem) -> Estimate {
        self.frames += 1;
        let generations = if self.needs_acquisition() {
            self.acquire(problem);
            self.settings.acquire_generations
        } else {
            self.track(problem);
            self.settings.generations_per_frame
        };
        let best_i = (0..self.pop.fit.len())
            .max_by(|&a, &b| self.pop.fit[a].score.total_cmp(&self.pop.fit[b].score))
            .unwrap_or(0);
        let best = self.pop.genes[best_i];
        let fitness = self.pop.fit[best_i];
        if let Some(last) = self.last_best {
            // Damped: a wrong prediction costs more than a missing one.
            self.velocity = std::array::from_fn(|i| 0.5 * (best[i] - last[i]));
        }
        self.last_best = Some(best);
        let tracked = fitness.f >= self.settings.min_fitness;
        self.searching = if tracked { 0 } else { self.searching + 1 };
        // Below the floor (or NaN) the pose is never called tracked.
        let status = if fitness.f.is_nan() || fitness.f < self.settings.lost_fitness {
            status::LOST
        } else if tracked {
            status::TRACKING
        } else if self.searching > self.settings.lost_after_frames {
            status::LOST
        } else {
            status::SEARCHING
        };
        Estimate {
            best: problem.bounds.decode(&best),
            fitness,
            generations: generations as u32,
            status,
        }
    }

    /// One-shot robust search, then a population around its answer.
    fn acquire(&mut self, problem: &Problem) {
        let seed = self.rng.random();
        let outcome = crate::ga::robust::run(
            problem,
            &self.ga,
            &self.robust,
            self.settings.acquire_generations,
            seed,
            &mut |_| {},
        );
        let best = problem.bounds.encode(&outcome.best);
        self.pop.genes.clear();
        self.pop.genes.push(best);
        while self.pop.genes.len() < self.settings.population {
            let mut g = best;
            mutate(&mut g, self.settings.sigma, &mut self.rng);
            self.pop.genes.push(g);
        }
        self.pop.fit.resize(self.pop.genes.len(), Fitness::default());
        problem.evaluate_batch(0, &self.pop.genes, &mut self.pop.fit);
        self.searching = 0;
        self.last_best = None;
        self.velocity = [0.0; GENES];
    }

    /// Predicts, re-scores and evolves the population on a new frame.
    fn track(&mut self, problem: &Problem) {
        for g in self.pop.genes.iter_mut() {
            for (v, d) in g.iter_mut().zip(self.velocity) {
                *v = (*v + d).clamp(0.0, 1.0);
            }
        }
        problem.evaluate_batch(0, &self.pop.genes, &mut self.pop.fit);
        let keep =
            ((self.pop.genes.len() as f64 * self.ga.survivors).round() as usize).clamp(1, self.pop.genes.len() - 1);
        let immigrants = if self.searching > 0 {
            self.settings.immigrants
        } else {
            0.0
        };
        // Searching widens the mutation too.
        let sigma = self.settings.sigma * if self.searching > 0 { 4.0 } else { 1.0 };
        for _ in 0..self.settings.generations_per_frame {
            self.pop.sort(&mut self.order);
            self.pop
                .breed(problem, keep, &self.ga, sigma, immigrants, &mut self.rng);
            problem.evaluate_batch(0, &self.pop.genes[keep..], &mut self.pop.fit[keep..]);
        }
    }
}

/// Pixels of each eye (left, right) worth preparing for a model at `pose`: the
/// projection of its `extent_px` (photo pixels: the box and its outer strip), grown on
/// every side by `grow` times its size and at least `min_px` (the motion until the next
/// frame and the population's spread). The whole image where it reaches behind a camera.
pub fn search_windows(
    rig: &StereoRig,
    left_from_hand: &Isometry3<f64>,
    pose: &PoseSize,
    extent_px: [f64; 2],
    grow: f64,
    min_px: f64,
) -> [Region; 2] {
    let left_from_model = left_from_hand * pose.hand_from_model();
    let size = pose.size_mm(extent_px[0], extent_px[1]);
    let (w, h) = (rig.width as usize, rig.height as usize);
    let pad = |extent: f64| (grow * extent).max(min_px);
    [
        Region::covering(&rig.left, [(left_from_model, size)], w, h, pad),
        Region::covering(&rig.right, [(rig.right_from_left * left_from_model, size)], w, h, pad),
    ]
}

/// Growth of the prepared window around the predicted model (with its outer strip), as a
/// share of its size, and its least margin in pixels: the population's spread and the
/// motion the prediction missed (a few pixels per frame at 60 fps).
const WINDOW_GROW: f64 = 0.1;
const WINDOW_MIN_PX: f64 = 24.0;

/// Why a frame could not be used.
#[derive(Debug, thiserror::Error)]
pub enum FrameError {
    #[error("payload of {len} bytes is smaller than its header says ({width}x{height} per eye, stride {stride})")]
    Incomplete {
        len: usize,
        width: usize,
        height: usize,
        stride: usize,
    },
    #[error(transparent)]
    Calibration(#[from] CalibrationError),
}

/// What the next [`StreamTracker::step`] works on.
enum Ready {
    /// Lookup regions around the prediction were refilled from the frame.
    Regions,
    /// The whole frame, for a one-shot acquisition.
    Acquire(Box<Prepared>),
}

/// The estimator's work on a stream of frames: each frame is first read
/// ([`StreamTracker::prepare`], while the caller holds it), then searched
/// ([`StreamTracker::step`], after the caller released it). Tracking frames convert only
/// the regions around the predicted pose, into lookup images allocated once.
pub struct StreamTracker {
    config: Config,
    model: PhotoModel,
    scorer: Scorer,
    bounds: Bounds,
    /// The model's points for tracking frames (scored at full resolution).
    points: [PointSet; 1],
    /// The model's extent with its outer strip, photo pixels.
    extent_px: [f64; 2],
    regions: Option<LevelLookup>,
    tracker: Tracker,
    ready: Option<Ready>,
}

impl StreamTracker {
    pub fn new(model: PhotoModel, config: Config) -> Self {
        let scorer = scorer_for(&model, &config);
        let bounds = Bounds::new(&config.search, &model, config.ga.mode == Mode::Robust);
        let points = [PointSet::from_model(
            &model,
            &scorer.params,
            config.tracking.point_stride,
        )];
        let tracker = Tracker::new(&config, config.ga.seed);
        let strip = 2.0 * model.outer_width_px;
        Self {
            extent_px: [model.l_p + strip, model.b_p + strip],
            config,
            model,
            scorer,
            bounds,
            points,
            regions: None,
            tracker,
            ready: None,
        }
    }

    /// Reads what the next step needs from a side-by-side RGB8 or YUYV frame.
    pub fn prepare(&mut self, frame: &SbsBytes) -> Result<(), FrameError> {
        self.ready = None;
        if !frame.is_complete() {
            return Err(FrameError::Incomplete {
                len: frame.bytes.len(),
                width: frame.width,
                height: frame.height,
                stride: frame.row_stride,
            });
        }
        let rig = self
            .config
            .calibration
            .rig_for_image(frame.width as u32, frame.height as u32)?;
        let ready = match self.tracker.prediction() {
            Some(genes) => {
                let regions = match &mut self.regions {
                    Some(r) if r.rig == rig => r,
                    slot => slot.insert(LevelLookup::regions(&rig)),
                };
                let rois = search_windows(
                    &rig,
                    &self.scorer.left_from_hand,
                    &self.bounds.decode(&genes),
                    self.extent_px,
                    WINDOW_GROW,
                    WINDOW_MIN_PX,
                );
                self.scorer.refill(regions, frame, &rois);
                Ready::Regions
            }
            None => {
                let images = frame.to_images().ok_or(FrameError::Incomplete {
                    len: frame.bytes.len(),
                    width: frame.width,
                    height: frame.height,
                    stride: frame.row_stride,
                })?;
                Ready::Acquire(Box::new(Prepared::new(&self.model, &images, &self.config)?))
            }
        };
        self.ready = Some(ready);
        Ok(())
    }

    /// Searches the prepared frame; `None` when no frame was prepared.
    pub fn step(&mut self) -> Option<Estimate> {
        Some(match self.ready.take()? {
            Ready::Regions => {
                let regions = std::slice::from_ref(self.regions.as_ref()?);
                let threads = self.config.tracking.threads;
                let problem = Problem::new(&self.scorer, regions, &self.points, self.bounds, threads);
                self.tracker.step(&problem)
            }
            Ready::Acquire(prepared) => self.tracker.step(&prepared.problem(&self.config)),
        })
    }

    /// The pose message of an estimate for frame `frame_id` (publish time not set),
    /// [sanitized](PoseMsg::sanitize): finite, unit quaternion, `lost` when it cannot be.
    pub fn pose_msg(&self, est: &Estimate, frame_id: u64, capture_time_ns: u64) -> PoseMsg {
        let b = &est.best;
        let mut pose = PoseMsg {
            frame_id,
            capture_time_ns,
            publish_time_ns: 0,
            position_mm: b.position.into(),
            orientation_wxyz: b.orientation_wxyz(),
            size_mm: b.size_mm(self.model.l_p, self.model.b_p),
            fitness: est.fitness.f,
            generations: est.generations,
            status: est.status,
        };
        pose.sanitize();
        pose
    }
}
