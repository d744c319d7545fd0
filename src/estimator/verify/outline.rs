//! A card's outline. A photo smooth near its border (the rocket in its sky) lines up
//! with the image about as well a few per cent larger or smaller: its texture says
//! little about where its sides are. But a card stands out from what lies behind it:
//! the brightness steps across each of its sides, at the same card points in both eyes.
//! [`contrast`] reads that step along the sides of a candidate.

use nalgebra::{Isometry3, Point2, Point3};

use super::plane::TwoEyes;
use super::texture::Brightness;
use crate::estimator::pose::PoseSize;

/// Points read along each side, over its middle [`SPAN`].
const ALONG: usize = 48;
const SPAN: f64 = 0.9;

/// How far inside and outside a side the brightness is read, in left-image pixels at
/// the candidate's centre: past the blur of a defocused edge, short of the texture
/// next to it.
const ACROSS_PX: f64 = 2.0;

/// The brightness step across the four sides of `c` (`box_px`: the photo box, for
/// sizes), 0–1: at 48 points along the middle 90 % of each side, the brightness 2 px
/// inside against outside, the smaller of the two eyes' steps; each side's mean step,
/// averaged over the sides.
pub fn contrast(two: &TwoEyes, c: &PoseSize, box_px: [f64; 2]) -> f64 {
    let left_from_model = two.left_from_hand * c.hand_from_model();
    let d = ACROSS_PX * left_from_model.translation.vector.norm() / two.rig.left.fx;
    let [l, b] = c.size_mm(box_px[0], box_px[1]);
    let sides = [(true, 1.0), (true, -1.0), (false, 1.0), (false, -1.0)];
    let steps = sides.iter().map(|&(length, sign)| {
        let (extent, across) = if length { (l, b) } else { (b, l) };
        side_step(two, &left_from_model, (length, sign * extent / 2.0, across), sign * d)
    });
    steps.sum::<f64>() / 4.0 / 255.0
}

/// The mean brightness step across one side: the side at `edge` mm along the length
/// (`length`) or the width, `across` mm long; read `d` mm (signed outwards) either side
/// of it, at each point the smaller of the two eyes' steps. A side of the card lies on
/// its plane, so both eyes see its step at the same card point; the edge of a bar in
/// front of the card, nearer, falls at different card points in the two eyes and is
/// left out. 0 where no point of it is in both eyes.
fn side_step(two: &TwoEyes, left_from_model: &Isometry3<f64>, (length, edge, across): (bool, f64, f64), d: f64) -> f64 {
    let (mut sum, mut n) = (0.0, 0);
    for i in 0..ALONG {
        let s = (-SPAN / 2.0 + SPAN * i as f64 / (ALONG - 1) as f64) * across;
        let on_card = |x: f64| {
            if length {
                Point3::new(x, s, 0.0)
            } else {
                Point3::new(s, x, 0.0)
            }
        };
        let [inside, outside] = [edge - d, edge + d].map(|x| two.rig.project_both(&(left_from_model * on_card(x))));
        let step = |eye: &Brightness, a: Option<Point2<f64>>, b: Option<Point2<f64>>| {
            let at = |p: Point2<f64>| eye.brightness_at(p.x as f32, p.y as f32);
            Some((at(a?)? - at(b?)?).abs() as f64)
        };
        let left = step(two.eyes[0], inside.0, outside.0);
        if let (Some(left), Some(right)) = (left, step(two.eyes[1], inside.1, outside.1)) {
            sum += left.min(right);
            n += 1;
        }
    }
    if n == 0 {
        0.0
    } else {
        sum / n as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Intrinsics, StereoRig};
    use crate::estimator::fitness::PointSet;
    use image::{Rgb, RgbImage};
    use nalgebra::Vector3;

    /// A white 100 × 80 mm card facing the rig at 500 mm on black, seen by both eyes
    /// (pinhole, 120 mm baseline): the step is whole at its true sides, gone where the
    /// sides are read 10 % out, half there with only the length stretched 5 %, and gone
    /// where only one eye sees it.
    #[test]
    fn the_step_is_read_at_the_cards_sides_only() {
        let camera = Intrinsics::pinhole(700.0, 700.0, 320.0, 240.0);
        let right_from_left = Isometry3::translation(-120.0, 0.0, 0.0);
        let eye = |shift: f64| {
            RgbImage::from_fn(640, 480, |u, v| {
                let x = (u as f64 - 320.0) / 700.0 * 500.0 + shift;
                let y = (v as f64 - 240.0) / 700.0 * 500.0;
                Rgb(if x.abs() <= 50.0 && y.abs() <= 40.0 {
                    [255; 3]
                } else {
                    [0; 3]
                })
            })
        };
        let (left, right) = (Brightness::of(&eye(0.0)), Brightness::of(&eye(120.0)));
        let rig = StereoRig {
            width: 640,
            height: 480,
            left: camera,
            right: camera,
            right_from_left,
        };
        let (points, identity) = (PointSet::default(), Isometry3::identity());
        let two = TwoEyes {
            points: &points,
            rig: &rig,
            eyes: [&left, &right],
            left_from_hand: &identity,
        };
        let box_px = [200.0, 160.0];
        let card = PoseSize::from_pose(
            &Isometry3::new(Vector3::new(0.0, 0.0, 500.0), Vector3::zeros()),
            [100.0, 80.0],
            200.0,
            160.0,
        );
        let at = |c: &PoseSize| contrast(&two, c, box_px);
        assert!(at(&card) > 0.95, "{}", at(&card));
        assert!(at(&card.scaled(1.1)) < 0.05, "{}", at(&card.scaled(1.1)));
        let stretched = at(&card.resized(box_px, true, 1.05, 0.0));
        assert!((0.45..0.55).contains(&stretched), "{stretched}");
        // A step that one eye sees and the other does not (a blank right eye): nothing.
        let blank = Brightness::of(&RgbImage::new(640, 480));
        let one_eye = TwoEyes {
            eyes: [&left, &blank],
            ..two
        };
        assert!(contrast(&one_eye, &card, box_px) < 1e-6);
    }
}
