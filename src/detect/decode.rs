//! Decoding a YOLO network's output tensor into scored boxes, whichever of the common
//! export layouts it has. The layout is recognised from the output shape:
//!
//! | layout | shape | one box | score of class c |
//! |---|---|---|---|
//! | [`Layout::Yolov8`] (Ultralytics YOLOv8, YOLO11) | `[1, 4 + C, N]` | a column: `cx, cy, w, h`, C class scores | `s_c` |
//! | [`Layout::Yolov5`] (YOLOv5; photopose's converted YOLOv3-tiny) | `[1, N, 5 + C]` | a row: `cx, cy, w, h`, objectness, C class probabilities | `obj · p_c` |
//!
//! Boxes are centre and size in network-input pixels; scores are already through the
//! sigmoid (as these exports produce them). Every class of a box that reaches the
//! minimum score is a candidate (multi-label), so a requested class is found even where
//! another class scores higher on the same box.

use super::{DetectError, Detection, Rect};

/// A recognised output layout.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Layout {
    /// `[1, 4 + C, N]`: attributes first, no objectness.
    Yolov8,
    /// `[1, N, 5 + C]`: one row per box, with objectness.
    Yolov5,
}

impl Layout {
    /// The layout of an output of `shape` for a network with `classes` classes.
    pub fn from_shape(shape: &[usize], classes: usize) -> Option<Layout> {
        match *shape {
            [1, a, n] if a == 4 + classes && n != 5 + classes => Some(Layout::Yolov8),
            [1, _, a] if a == 5 + classes => Some(Layout::Yolov5),
            _ => None,
        }
    }
}

/// What one output holds: the candidate boxes at or above the minimum score (input
/// pixels, before NMS) and the best score each class reached anywhere.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Decoded {
    /// One detection per box and class scoring at least the minimum, input pixels.
    pub candidates: Vec<Detection>,
    /// The best score of each class over all boxes, indexed by class id.
    pub best_score: Vec<f32>,
}

/// Decodes `data`, an output of `shape`, for `classes` classes.
pub fn decode(data: &[f32], shape: &[usize], classes: usize, min_score: f32) -> Result<Decoded, DetectError> {
    let layout = Layout::from_shape(shape, classes).ok_or_else(|| DetectError::UnsupportedOutput {
        shape: shape.to_vec(),
        classes,
    })?;
    let expected: usize = shape.iter().product();
    if data.len() != expected {
        return Err(DetectError::OutputLength {
            shape: shape.to_vec(),
            len: data.len(),
        });
    }
    // Element `attr` of box `i` is at `attr · attr_stride + i · box_stride`.
    let (boxes, attr_stride, box_stride, first_class, objectness) = match layout {
        Layout::Yolov8 => (shape[2], shape[2], 1, 4, None),
        Layout::Yolov5 => (shape[1], 1, shape[2], 5, Some(4)),
    };
    let mut out = Decoded {
        candidates: Vec::new(),
        best_score: vec![0.0; classes],
    };
    for i in 0..boxes {
        let at = |attr: usize| data[attr * attr_stride + i * box_stride];
        let (cx, cy, w, h) = (at(0), at(1), at(2), at(3));
        if !(cx.is_finite() && cy.is_finite() && w.is_finite() && h.is_finite() && w > 0.0 && h > 0.0) {
            continue;
        }
        let obj = objectness.map_or(1.0, at);
        for (class, best) in out.best_score.iter_mut().enumerate() {
            let score = obj * at(first_class + class);
            if !score.is_finite() {
                continue;
            }
            *best = best.max(score);
            if score >= min_score {
                out.candidates.push(Detection {
                    class,
                    score,
                    rect: Rect::from_center(cx, cy, w, h),
                });
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    const C: usize = 80;

    /// One box as (cx, cy, w, h, objectness, [(class, score)]).
    type Box = (f32, f32, f32, f32, f32, Vec<(usize, f32)>);

    /// A `[1, 4 + C, N]` tensor (Ultralytics YOLOv8/YOLO11 export).
    fn yolov8(boxes: &[Box]) -> (Vec<f32>, Vec<usize>) {
        let n = boxes.len();
        let mut t = vec![0.0; (4 + C) * n];
        for (i, (cx, cy, w, h, _, scores)) in boxes.iter().enumerate() {
            for (a, v) in [cx, cy, w, h].into_iter().enumerate() {
                t[a * n + i] = *v;
            }
            for (c, s) in scores {
                t[(4 + c) * n + i] = *s;
            }
        }
        (t, vec![1, 4 + C, n])
    }

    /// A `[1, N, 5 + C]` tensor (YOLOv5 export, photopose's YOLOv3-tiny).
    fn yolov5(boxes: &[Box]) -> (Vec<f32>, Vec<usize>) {
        let mut t = Vec::new();
        for (cx, cy, w, h, obj, scores) in boxes {
            let mut row = vec![0.0; 5 + C];
            row[..5].copy_from_slice(&[*cx, *cy, *w, *h, *obj]);
            for (c, s) in scores {
                row[5 + c] = *s;
            }
            t.extend(row);
        }
        (t, vec![1, boxes.len(), 5 + C])
    }

    fn boxes() -> Vec<Box> {
        vec![
            (100.0, 80.0, 40.0, 60.0, 0.9, vec![(41, 0.8), (45, 0.5)]),
            (300.0, 200.0, 100.0, 50.0, 0.5, vec![(0, 0.9)]),
            (10.0, 10.0, 5.0, 5.0, 0.1, vec![(2, 0.3)]),
        ]
    }

    #[test]
    fn layouts_are_recognised_from_the_shape() {
        assert_eq!(Layout::from_shape(&[1, 84, 8400], 80), Some(Layout::Yolov8));
        assert_eq!(Layout::from_shape(&[1, 25200, 85], 80), Some(Layout::Yolov5));
        assert_eq!(Layout::from_shape(&[1, 2535, 85], 80), Some(Layout::Yolov5));
        assert_eq!(Layout::from_shape(&[1, 84, 85], 80), Some(Layout::Yolov5));
        assert_eq!(Layout::from_shape(&[1, 8400, 84], 80), None);
        assert_eq!(Layout::from_shape(&[2, 84, 8400], 80), None);
        assert_eq!(Layout::from_shape(&[84, 8400], 80), None);
        let e = decode(&[0.0; 6], &[1, 2, 3], 80, 0.25).unwrap_err().to_string();
        assert!(
            e.contains("[1, 2, 3]") && e.contains("[1, 84, N]") && e.contains("[1, N, 85]"),
            "{e}"
        );
    }

    #[test]
    fn yolov8_columns_decode_without_objectness() {
        let (t, shape) = yolov8(&boxes());
        let d = decode(&t, &shape, C, 0.25).unwrap();
        // Box 0: cup 0.8 and bowl 0.5; box 1: person 0.9; box 2: car 0.3 (no objectness in v8).
        let got: Vec<(usize, f32)> = d.candidates.iter().map(|c| (c.class, c.score)).collect();
        assert_eq!(got, vec![(41, 0.8), (45, 0.5), (0, 0.9), (2, 0.3)]);
        let cup = &d.candidates[0];
        assert_eq!(
            (cup.rect.x0, cup.rect.y0, cup.rect.x1, cup.rect.y1),
            (80.0, 50.0, 120.0, 110.0)
        );
        assert_eq!(d.best_score[41], 0.8);
        assert_eq!(d.best_score[7], 0.0);
    }

    #[test]
    fn yolov5_rows_multiply_objectness() {
        let (t, shape) = yolov5(&boxes());
        let d = decode(&t, &shape, C, 0.25).unwrap();
        let got: Vec<(usize, f32)> = d.candidates.iter().map(|c| (c.class, c.score)).collect();
        // 0.9·0.8, 0.9·0.5, 0.5·0.9; the car (0.1·0.3) stays below the threshold.
        assert_eq!(got, vec![(41, 0.9 * 0.8), (45, 0.9 * 0.5), (0, 0.5 * 0.9)]);
        let person = &d.candidates[2].rect;
        assert_eq!(
            (person.x0, person.y0, person.x1, person.y1),
            (250.0, 175.0, 350.0, 225.0)
        );
        assert!(
            (d.best_score[2] - 0.03).abs() < 1e-6,
            "best score is kept below the threshold"
        );
    }

    #[test]
    fn degenerate_boxes_and_wrong_lengths_are_rejected() {
        let mut b = boxes();
        b[0].2 = 0.0; // zero width
        b[1].0 = f32::NAN;
        let (t, shape) = yolov5(&b);
        let d = decode(&t, &shape, C, 0.25).unwrap();
        assert!(d.candidates.is_empty());
        let e = decode(&t[1..], &shape, C, 0.25).unwrap_err().to_string();
        assert!(e.contains("[1, 3, 85]") && e.contains("254"), "{e}");
    }
}
