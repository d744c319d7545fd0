//! The photo-model's outline in the left image: its inner box (the card, L × B) and
//! the outer edge of its strip, projected through the calibrated lens, and a colour per
//! estimator status.

use nalgebra::{Isometry3, Point3};

use crate::camera::Intrinsics;
use crate::transport::messages::Status;

/// Points along each edge of a projected box: enough for the lens distortion to show.
const PER_EDGE: usize = 12;

/// The closed polylines (pixels) of the card's box `size_mm` (L × B) and of the box
/// grown by `strip_mm` on each side, for the model at `hand_from_model`, seen by the left
/// camera `camera` at `left_from_hand`. A box with a corner behind the camera is left
/// out.
pub fn card_outline(
    hand_from_model: &Isometry3<f64>,
    size_mm: [f64; 2],
    strip_mm: f64,
    left_from_hand: &Isometry3<f64>,
    camera: &Intrinsics,
) -> Vec<Vec<[f32; 2]>> {
    let left_from_model = left_from_hand * hand_from_model;
    let [hl, hb] = size_mm.map(|s| s / 2.0);
    let boxes = if strip_mm > 0.0 {
        vec![(hl, hb), (hl + strip_mm, hb + strip_mm)]
    } else {
        vec![(hl, hb)]
    };
    boxes
        .into_iter()
        .filter_map(|(x, y)| {
            let corners = [(-x, -y), (x, -y), (x, y), (-x, y), (-x, -y)];
            let mut line = Vec::with_capacity(4 * PER_EDGE + 1);
            for w in corners.windows(2) {
                let n = if w[1] == corners[4] { PER_EDGE + 1 } else { PER_EDGE };
                for i in 0..n {
                    let t = i as f64 / PER_EDGE as f64;
                    let (px, py) = (w[0].0 + t * (w[1].0 - w[0].0), w[0].1 + t * (w[1].1 - w[0].1));
                    let p = camera.project(&(left_from_model * Point3::new(px, py, 0.0)))?;
                    line.push([p.x as f32, p.y as f32]);
                }
            }
            Some(line)
        })
        .collect()
}

/// Green for `tracking`, amber for `searching`, red for `lost` and any other code.
pub fn status_colour(status: u32) -> [u8; 3] {
    match Status::try_from(status) {
        Ok(Status::Tracking) => [40, 220, 60],
        Ok(Status::Searching) => [255, 180, 0],
        _ => [230, 40, 40],
    }
}

/// The colour of the truth beside the estimate.
pub const TRUTH_COLOUR: [u8; 3] = [70, 140, 255];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_card_facing_the_camera_projects_to_a_centred_box() {
        let camera = Intrinsics::pinhole(1000.0, 1000.0, 640.0, 360.0);
        let at = Isometry3::translation(0.0, 0.0, 500.0);
        let lines = card_outline(&at, [100.0, 50.0], 10.0, &Isometry3::identity(), &camera);
        assert_eq!(lines.len(), 2);
        let inner = &lines[0];
        assert_eq!(inner.len(), 4 * PER_EDGE + 1);
        assert_eq!(inner.first(), inner.last(), "closed");
        // 100 mm at 500 mm with f = 1000 px: 200 px wide, centred on the principal point.
        assert_eq!(inner[0], [540.0, 310.0]);
        assert_eq!(inner[PER_EDGE], [740.0, 310.0]);
        assert_eq!(inner[2 * PER_EDGE], [740.0, 410.0]);
        // The strip's edge is 10 mm (20 px) further out.
        assert_eq!(lines[1][0], [520.0, 290.0]);
    }

    #[test]
    fn a_card_behind_the_camera_has_no_outline_and_statuses_differ() {
        let camera = Intrinsics::pinhole(1000.0, 1000.0, 640.0, 360.0);
        let behind = Isometry3::translation(0.0, 0.0, -500.0);
        assert!(card_outline(&behind, [100.0, 50.0], 0.0, &Isometry3::identity(), &camera).is_empty());
        let colours = [0, 1, 2].map(status_colour);
        assert!(colours[0] != colours[1] && colours[1] != colours[2]);
        assert_eq!(status_colour(7), status_colour(2), "unknown codes as lost");
    }
}
