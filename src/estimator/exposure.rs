//! Light that changes while an object is tracked. Exposure and white balance drift
//! (gains of 0.5–1.5× per channel) move pixels across the colour classes' brightness
//! thresholds and shift their hues, so a tracked model's `F` falls although its pose is
//! right. The card's own points are read on the frame it was acquired on, at the
//! acquired pose (the reference), and at the predicted pose of every tracked frame
//! after it; over the middle half of the points by brightness ratio, each channel's
//! ratio gives the gain that brings the frame back to the reference's light, and its
//! texels are classed after them ([`crate::vision::lookup::TexelRule::gains`]).

use image::RgbImage;
use nalgebra::Isometry3;

use crate::camera::StereoRig;
use crate::estimator::fitness::{PointProjector, PointSet};
use crate::estimator::pose::PoseSize;
use crate::vision::lookup::{gained, SbsBytes, CLIPPED};

/// Model points read per frame (spread evenly over the model's inner points).
const SAMPLES: usize = 256;
/// Half the side of the square of pixels averaged per point: a pose a pixel or two off
/// reads nearly the same colour.
const PATCH: isize = 2;
/// A reference point whose channels sum to less than this gives no ratio (too noisy).
const DARKEST: f32 = 36.0;
/// Share of the points that must give a ratio for the gains to be updated.
const MIN_SHARE: f64 = 0.3;
/// Largest interquartile range of the brightness ratios, relative to their median (on a
/// tracked card under changing light about 0.1): wider, and the points do not read the
/// card they read on the reference frame (the prediction missed, blur, an occluder), so
/// the gains stay as they were.
const MAX_SPREAD: f32 = 0.3;
/// Largest change of a gain from one frame to the next, as a factor: light changes over
/// many frames (0.55–1.45× in 1.5 s is 2 % a frame at 30 fps); one frame misread must
/// not recolour the next.
const MAX_STEP: f32 = 1.1;
/// Gains all within this share of 1 are taken as 1: in steady light the gains read on
/// a blurred card moving at 600 mm/s wander by up to 7 %, and applying them cost the
/// `sweep` sequence more than half its tracked frames.
const STEADY: f32 = 0.1;
/// The gains are kept within this range.
const GAIN_RANGE: [f32; 2] = [0.4, 2.5];

/// The gains that undo the light's change since the reference frame.
#[derive(Debug, Clone)]
pub struct Exposure {
    /// The points read, photo pixels from the box centre.
    points: Vec<[f32; 2]>,
    /// Their colour on the reference frame (NaN: not read); empty until it is taken.
    reference: Vec<[f32; 3]>,
    gains: [f32; 3],
    /// The current frame's readable points: brightness ratio to the reference, the
    /// reference's colour and this frame's (allocated once).
    pairs: Vec<(f32, [f32; 3], [f32; 3])>,
    /// The brightness ratios, for their quartiles.
    ratios: Vec<f32>,
    /// Points the reference could not read, with this frame's colour.
    unknown: Vec<(usize, [f32; 3])>,
}

impl Exposure {
    /// Reads about `SAMPLES` of the inner points of `points`.
    pub fn new(points: &PointSet) -> Self {
        let n = points.inner_x.len();
        let step = n.div_ceil(SAMPLES).max(1);
        let points: Vec<[f32; 2]> = (0..n)
            .step_by(step)
            .map(|i| [points.inner_x[i], points.inner_y[i]])
            .collect();
        Self {
            pairs: Vec::with_capacity(points.len()),
            unknown: Vec::with_capacity(points.len()),
            ratios: Vec::with_capacity(points.len()),
            reference: Vec::with_capacity(points.len()),
            points,
            gains: [1.0; 3],
        }
    }

    /// A new acquisition: unit gains until its reference is set.
    pub fn reset(&mut self) {
        self.reference.clear();
        self.gains = [1.0; 3];
    }

    /// The current gains `[r, g, b]`.
    pub fn gains(&self) -> [f32; 3] {
        self.gains
    }

    /// Reads the model's points at `pose` (hand frame) in `left`, the left image of the
    /// frame the object was acquired on: the light the gains restore.
    pub fn set_reference(
        &mut self,
        left: &RgbImage,
        rig: &StereoRig,
        left_from_hand: &Isometry3<f64>,
        pose: &PoseSize,
    ) {
        let pixel = |u: usize, v: usize| left.get_pixel_checked(u as u32, v as u32).map(|p| p.0);
        let project = PointProjector::new(&rig.left, &(left_from_hand * pose.hand_from_model()), pose);
        self.reference.clear();
        let read = |&[x, y]: &[f32; 2]| patch_mean(&pixel, project.pixel(x, y)).unwrap_or([f32::NAN; 3]);
        self.reference.extend(self.points.iter().map(read));
        self.gains = [1.0; 3];
    }

    /// Reads the model's points at `pose` (hand frame) in the left eye of `frame`, and
    /// from them the gains that bring the frame back to the reference's light (unit gains
    /// until a reference is set), changing by at most `MAX_STEP` a frame. The caller
    /// passes the pose of a tracked object only. A point the reference could not read
    /// (clipped, outside the image) is learnt from the first frame that reads it, in the
    /// reference's light.
    pub fn update(
        &mut self,
        frame: &SbsBytes,
        rig: &StereoRig,
        left_from_hand: &Isometry3<f64>,
        pose: &PoseSize,
    ) -> [f32; 3] {
        if self.reference.is_empty() {
            return self.gains;
        }
        let pixel = |u: usize, v: usize| frame.rgb_at(0, u, v);
        let project = PointProjector::new(&rig.left, &(left_from_hand * pose.hand_from_model()), pose);
        self.pairs.clear();
        self.unknown.clear();
        for (i, (&[x, y], r)) in self.points.iter().zip(&self.reference).enumerate() {
            let Some(now) = patch_mean(&pixel, project.pixel(x, y)) else {
                continue;
            };
            let brightness = r.iter().sum::<f32>();
            if r[0].is_nan() {
                self.unknown.push((i, now));
            } else if brightness >= DARKEST {
                self.pairs.push((now.iter().sum::<f32>() / brightness, *r, now));
            }
        }
        let Some(measured) = self.gains_of_pairs() else {
            return self.gains;
        };
        for &(i, now) in &self.unknown {
            self.reference[i] = gained(now, measured);
        }
        let steady = measured.iter().all(|g| (g - 1.0).abs() < STEADY);
        let target = if steady { [1.0; 3] } else { measured };
        let step = |k: usize| target[k].clamp(self.gains[k] / MAX_STEP, self.gains[k] * MAX_STEP);
        self.gains = std::array::from_fn(step);
        self.gains
    }

    /// The gains from this frame's [`Exposure::pairs`]: each channel's over the middle
    /// half of the points by brightness ratio. `None` when too few points were read or
    /// their ratios spread too widely.
    fn gains_of_pairs(&mut self) -> Option<[f32; 3]> {
        if (self.pairs.len() as f64) < MIN_SHARE * self.points.len() as f64 {
            return None;
        }
        self.ratios.clear();
        self.ratios.extend(self.pairs.iter().map(|p| p.0));
        let [q1, median, q3] = quartiles(&mut self.ratios);
        if median <= 0.0 || (q3 - q1) / median > MAX_SPREAD {
            return None;
        }
        let (mut then, mut now) = ([0.0f32; 3], [0.0f32; 3]);
        for (_, r, c) in self.pairs.iter().filter(|p| (q1..=q3).contains(&p.0)) {
            (0..3).for_each(|k| (then[k], now[k]) = (then[k] + r[k], now[k] + c[k]));
        }
        Some(std::array::from_fn(|k| {
            (then[k] / now[k].max(1.0)).clamp(GAIN_RANGE[0], GAIN_RANGE[1])
        }))
    }
}

/// The mean colour of the `(2·PATCH + 1)²` pixels around `(u, v)` of an image read
/// through `pixel`; `None` unless all of them are inside the image and none is clipped.
fn patch_mean(pixel: &impl Fn(usize, usize) -> Option<[u8; 3]>, (u, v): (f32, f32)) -> Option<[f32; 3]> {
    let (u, v) = (u.round() as isize, v.round() as isize);
    let mut sum = [0.0f32; 3];
    for dv in -PATCH..=PATCH {
        for du in -PATCH..=PATCH {
            let (x, y) = (usize::try_from(u + du).ok()?, usize::try_from(v + dv).ok()?);
            let px = pixel(x, y)?.map(f32::from);
            if px.iter().any(|&c| c >= CLIPPED) {
                return None;
            }
            (0..3).for_each(|c| sum[c] += px[c]);
        }
    }
    let n = ((2 * PATCH + 1) * (2 * PATCH + 1)) as f32;
    Some(sum.map(|s| s / n))
}

/// The first quartile, median and third quartile of `values` (reordered).
fn quartiles(values: &mut [f32]) -> [f32; 3] {
    let n = values.len();
    [n / 4, n / 2, (3 * n) / 4].map(|k| *values.select_nth_unstable_by(k.min(n - 1), f32::total_cmp).1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::calibration::Resolution;
    use crate::config::Config;
    use crate::vision::PixelFormat;

    /// The default HD rig and hand–eye transform, and a 100 × 80 px model of 20 × 20
    /// points 600 mm in front of the left camera.
    struct Bench {
        config: Config,
        rig: StereoRig,
        points: PointSet,
        pose: PoseSize,
    }

    impl Bench {
        fn new() -> Self {
            let config = Config::load(None).expect("defaults");
            let rig = config.calibration.rig(Resolution::HD).expect("HD");
            let points = PointSet {
                inner_x: (0..400).map(|i| (i % 20) as f32 * 5.0 - 50.0).collect(),
                inner_y: (0..400).map(|i| (i / 20) as f32 * 4.0 - 40.0).collect(),
                ..PointSet::default()
            };
            let left_from_model = Isometry3::translation(0.0, 0.0, 600.0);
            let hand_from_model = config.left_from_hand.inverse() * left_from_model;
            let pose = PoseSize::from_pose(&hand_from_model, [100.0, 80.0], 100.0, 80.0);
            Self {
                config,
                rig,
                points,
                pose,
            }
        }

        /// An exposure whose reference is a left image of `colour(x, y)`.
        fn exposure(&self, colour: fn(u32, u32) -> [f32; 3]) -> Exposure {
            let left = RgbImage::from_fn(self.rig.width, self.rig.height, |x, y| {
                image::Rgb(colour(x, y).map(|c| c.round() as u8))
            });
            let mut exposure = Exposure::new(&self.points);
            exposure.set_reference(&left, &self.rig, &self.config.left_from_hand, &self.pose);
            exposure
        }

        /// The gains after a side-by-side RGB8 frame whose left eye is `colour(x, y)`
        /// times `gains`.
        fn update(&self, exposure: &mut Exposure, gains: [f32; 3], colour: fn(u32, u32) -> [f32; 3]) -> [f32; 3] {
            let (w, h) = (self.rig.width as usize, self.rig.height as usize);
            let mut bytes = vec![0u8; 6 * w * h];
            for (i, px) in bytes.chunks_exact_mut(3).enumerate() {
                let (x, y) = (i % (2 * w), i / (2 * w));
                let c = colour(x as u32, y as u32);
                (0..3).for_each(|k| px[k] = (c[k] * gains[k]).round().min(255.0) as u8);
            }
            let frame = SbsBytes {
                bytes: &bytes,
                width: w,
                height: h,
                row_stride: 6 * w,
                format: PixelFormat::Rgb8,
            };
            exposure.update(&frame, &self.rig, &self.config.left_from_hand, &self.pose)
        }

        /// The gains after 12 such frames.
        fn settle(&self, exposure: &mut Exposure, gains: [f32; 3], colour: fn(u32, u32) -> [f32; 3]) -> [f32; 3] {
            (0..12).fold([0.0; 3], |_, _| self.update(exposure, gains, colour))
        }
    }

    /// Colours changing smoothly across the image.
    fn ramp(x: u32, y: u32) -> [f32; 3] {
        [40.0 + 0.15 * x as f32, 60.0 + 0.15 * y as f32, 120.0]
    }

    fn close(gains: [f32; 3], want: [f32; 3]) -> bool {
        gains.iter().zip(want).all(|(g, w)| (g - w).abs() < 0.03 * w)
    }

    #[test]
    fn gains_undo_a_change_of_exposure_and_white_balance() {
        let bench = Bench::new();
        let mut exposure = bench.exposure(ramp);
        assert_eq!(bench.update(&mut exposure, [1.0; 3], ramp), [1.0; 3]);
        // At most 10 % a frame: settled after 8 frames.
        let first = bench.update(&mut exposure, [0.6, 0.5, 0.7], ramp);
        assert!(close(first, [1.1; 3]), "gains {first:?}");
        let gains = bench.settle(&mut exposure, [0.6, 0.5, 0.7], ramp);
        assert!(close(gains, [1.0 / 0.6, 2.0, 1.0 / 0.7]), "gains {gains:?}");
        // Within 10 % of 1 is steady light: unit gains.
        assert_eq!(bench.settle(&mut exposure, [0.93, 1.0, 1.08], ramp), [1.0; 3]);
        // A new acquisition: unit gains until its reference is set.
        exposure.reset();
        assert_eq!(bench.update(&mut exposure, [0.6, 0.5, 0.7], ramp), [1.0; 3]);
    }

    #[test]
    fn points_that_read_something_else_leave_the_gains_alone() {
        let bench = Bench::new();
        let mut exposure = bench.exposure(ramp);
        let brighter = bench.settle(&mut exposure, [1.25; 3], ramp);
        assert!(close(brighter, [0.8; 3]), "gains {brighter:?}");
        // A checkerboard of 16 px squares where the card was: not the same surface.
        let checks = |x: u32, y: u32| [[30.0, 220.0][((x / 16 + y / 16) % 2) as usize]; 3];
        assert_eq!(bench.update(&mut exposure, [1.0; 3], checks), brighter);
        // Clipped pixels give no ratio: none left, the gains stay.
        assert_eq!(bench.update(&mut exposure, [1.0; 3], |_, _| [255.0; 3]), brighter);
    }

    #[test]
    fn points_clipped_on_the_reference_are_learnt_in_its_light() {
        let bench = Bench::new();
        // The reference is clipped on the right half of the card (x ≥ 640).
        let mut exposure = bench.exposure(|x, y| if x >= 640 { [255.0; 3] } else { ramp(x, y) });
        bench.update(&mut exposure, [0.5; 3], ramp);
        // The right half, learnt at 2 × its reading (the gains measured on the left
        // half), agrees with the left half from then on.
        assert_eq!(exposure.reference.iter().filter(|r| r[0].is_nan()).count(), 0);
        let gains = bench.settle(&mut exposure, [0.4; 3], ramp);
        assert!(close(gains, [2.5; 3]), "gains {gains:?}");
    }

    #[test]
    fn quartiles_of_a_few_values() {
        let mut values = vec![1.0, 0.2, 3.0, 0.9, 1.1];
        assert_eq!(quartiles(&mut values), [0.9, 1.0, 1.1]);
    }
}
