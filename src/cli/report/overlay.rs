//! Pictures of a result (the paper's Fig. 9): the best model's inner points, outer
//! strip and outline projected onto the left and right images; and of a photo-model on
//! its own photo (`photopose model --overlay`).

use image::{Rgb, RgbImage};

use crate::camera::StereoRig;
use crate::estimator::fitness::{PointSet, ProjectedPoints, Scorer};
use crate::estimator::model::PhotoModel;
use crate::estimator::pose::PoseSize;
use crate::vision::frame::StereoImages;

const INNER: Rgb<u8> = Rgb([40, 255, 40]);
const OUTER: Rgb<u8> = Rgb([255, 40, 255]);
const OUTLINE: Rgb<u8> = Rgb([255, 255, 0]);

/// The side-by-side frame with the candidate's projection drawn on both eyes.
pub fn draw(images: &StereoImages, scorer: &Scorer, rig: &StereoRig, model: &PhotoModel, cand: &PoseSize) -> RgbImage {
    let mut out = images.to_sbs();
    let points = PointSet::from_model(model, &scorer.params, 1);
    let projected = scorer.project_points(&points, rig, cand);
    let outline = outline_points(model);
    let corners = scorer.project_points(&outline, rig, cand);
    let eye_w = images.left.width() as f64;
    for (eye, (pts, line)) in projected.iter().zip(&corners).enumerate() {
        let dx = eye as f64 * eye_w;
        draw_dots(&mut out, pts, dx, eye_w);
        for p in line.inner.iter().flatten() {
            dot(&mut out, p.x + dx, p.y, 1, OUTLINE, dx, eye_w);
        }
    }
    out
}

/// The photo with the model's box (yellow), inner points (green) and outer strip
/// (magenta) drawn on it, at the photo's pixels.
pub fn draw_model(photo: &RgbImage, model: &PhotoModel) -> RgbImage {
    let mut out = photo.clone();
    let (w, h) = (photo.width() as f64, photo.height() as f64);
    let b = model.bbox;
    let (cx, cy) = (b.x as f64 + b.w as f64 / 2.0, b.y as f64 + b.h as f64 / 2.0);
    // 2 × 2 pixel dots: visible, yet the photo shows between them.
    let mut dot2 = |x: f64, y: f64, colour| {
        for (dx, dy) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
            dot(&mut out, x - 0.5 + dx, y - 0.5 + dy, 0, colour, 0.0, w);
        }
    };
    for p in &model.outer {
        dot2(cx + p[0], cy + p[1], OUTER);
    }
    for p in &model.inner {
        dot2(cx + p.x, cy + p.y, INNER);
    }
    let (x0, y0) = (b.x as f64, b.y as f64);
    let (x1, y1) = ((b.x + b.w) as f64 - 1.0, (b.y + b.h) as f64 - 1.0);
    for i in 0..=b.w.max(b.h) {
        let t = i as f64 / b.w.max(b.h).max(1) as f64;
        let (x, y) = (x0 + t * (x1 - x0), y0 + t * (y1 - y0));
        for (px, py) in [(x, y0), (x, y1), (x0, y), (x1, y)] {
            dot(
                &mut out,
                px.clamp(0.0, w - 1.0),
                py.clamp(0.0, h - 1.0),
                1,
                OUTLINE,
                0.0,
                w,
            );
        }
    }
    out
}

fn draw_dots(img: &mut RgbImage, pts: &ProjectedPoints, dx: f64, eye_w: f64) {
    for p in pts.outer.iter().flatten() {
        dot(img, p.x + dx, p.y, 0, OUTER, dx, eye_w);
    }
    for p in pts.inner.iter().flatten() {
        dot(img, p.x + dx, p.y, 0, INNER, dx, eye_w);
    }
}

/// Densely sampled box border as "inner" points, so its projection is a curve.
fn outline_points(model: &PhotoModel) -> PointSet {
    let (hw, hh) = (model.l_p / 2.0, model.b_p / 2.0);
    let mut set = PointSet::default();
    let n = 400;
    for i in 0..=n {
        let t = i as f64 / n as f64;
        for (x, y) in [
            (-hw + t * 2.0 * hw, -hh),
            (-hw + t * 2.0 * hw, hh),
            (-hw, -hh + t * 2.0 * hh),
            (hw, -hh + t * 2.0 * hh),
        ] {
            set.inner_x.push(x as f32);
            set.inner_y.push(y as f32);
            set.inner_code.push(0);
            set.inner_sat.push(0);
            set.inner_v.push(0);
        }
    }
    set
}

/// A square dot of half-width `r` clipped to one eye `[x0, x0 + w)`.
fn dot(img: &mut RgbImage, x: f64, y: f64, r: i64, colour: Rgb<u8>, x0: f64, w: f64) {
    let (cx, cy) = (x.round() as i64, y.round() as i64);
    for yy in cy - r..=cy + r {
        for xx in cx - r..=cx + r {
            let inside_eye = (xx as f64) >= x0 && (xx as f64) < x0 + w;
            if inside_eye && yy >= 0 && (yy as u32) < img.height() && xx >= 0 && (xx as u32) < img.width() {
                img.put_pixel(xx as u32, yy as u32, colour);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimator::settings::ModelSettings;
    use crate::vision::color::ColorClasses;
    use std::path::Path;

    #[test]
    fn model_overlay_draws_box_and_points_on_the_photo() {
        let photo = RgbImage::from_pixel(80, 60, Rgb([10, 10, 10]));
        let settings = ModelSettings {
            step_px: 6.0,
            outer_width_px: 6.0,
            ..ModelSettings::default()
        };
        let model = PhotoModel::build(
            &photo,
            Path::new("p.png"),
            [20, 10, 40, 30],
            &settings,
            &ColorClasses::default(),
        )
        .expect("model");
        let pic = draw_model(&photo, &model);
        assert_eq!(pic.dimensions(), (80, 60));
        assert_eq!(*pic.get_pixel(20, 10), OUTLINE, "top-left corner");
        assert_eq!(*pic.get_pixel(59, 39), OUTLINE, "bottom-right corner");
        let count = |c: Rgb<u8>| pic.pixels().filter(|p| **p == c).count();
        assert!(count(INNER) >= model.inner.len(), "{} green pixels", count(INNER));
        assert!(count(OUTER) > 0);
        assert_eq!(*pic.get_pixel(0, 59), Rgb([10, 10, 10]), "far from the box: untouched");
    }
}
