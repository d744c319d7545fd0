//! Per-class non-maximum suppression: of boxes of the same class that overlap by more
//! than an IoU threshold, only the highest-scoring one is kept.

use super::Detection;

/// Keeps, per class, each box that overlaps no better-scoring kept box of its class by
/// more than `iou_threshold`. Returns them best first.
pub fn nms(mut candidates: Vec<Detection>, iou_threshold: f32) -> Vec<Detection> {
    candidates.sort_by(|a, b| b.score.total_cmp(&a.score).then(a.class.cmp(&b.class)));
    let mut kept: Vec<Detection> = Vec::new();
    for c in candidates {
        let suppressed = kept
            .iter()
            .any(|k| k.class == c.class && k.rect.iou(&c.rect) > iou_threshold);
        if !suppressed {
            kept.push(c);
        }
    }
    kept
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::Rect;

    fn rect(x0: f32, y0: f32, x1: f32, y1: f32) -> Rect {
        Rect { x0, y0, x1, y1 }
    }

    fn cand(class: usize, score: f32, x0: f32, y0: f32, x1: f32, y1: f32) -> Detection {
        Detection {
            class,
            score,
            rect: rect(x0, y0, x1, y1),
        }
    }

    #[test]
    fn iou_of_known_boxes() {
        let a = rect(0.0, 0.0, 10.0, 10.0);
        let b = rect(5.0, 0.0, 15.0, 10.0);
        assert!((a.iou(&b) - 50.0 / 150.0).abs() < 1e-6);
        assert_eq!(a.iou(&a), 1.0);
        let far = rect(20.0, 20.0, 30.0, 30.0);
        assert_eq!(a.iou(&far), 0.0);
        let empty = rect(3.0, 3.0, 3.0, 3.0);
        assert_eq!(empty.iou(&empty), 0.0);
    }

    #[test]
    fn overlapping_boxes_of_one_class_collapse_to_the_best() {
        let kept = nms(
            vec![
                cand(41, 0.6, 0.0, 0.0, 100.0, 100.0),
                cand(41, 0.9, 5.0, 5.0, 105.0, 105.0), // IoU ≈ 0.82 with the first
                cand(41, 0.7, 200.0, 0.0, 300.0, 100.0), // a second cup, apart
                cand(45, 0.5, 0.0, 0.0, 100.0, 100.0), // another class on the same spot
                cand(41, 0.4, 50.0, 0.0, 150.0, 100.0), // IoU 0.35 with the best: kept at 0.45
            ],
            0.45,
        );
        let got: Vec<(usize, f32)> = kept.iter().map(|c| (c.class, c.score)).collect();
        assert_eq!(got, vec![(41, 0.9), (41, 0.7), (45, 0.5), (41, 0.4)]);
        assert_eq!(kept[0].rect.x0, 5.0);
        // A stricter threshold also removes the partly overlapping cup.
        let strict = nms(
            vec![
                cand(41, 0.9, 5.0, 5.0, 105.0, 105.0),
                cand(41, 0.4, 50.0, 0.0, 150.0, 100.0),
            ],
            0.2,
        );
        assert_eq!(strict.len(), 1);
    }
}
