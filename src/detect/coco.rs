//! The 80 COCO class names, in the order every COCO-trained YOLO numbers them, and the
//! lookup `--class NAME` uses.

use super::DetectError;

/// The COCO 2017 names (as Ultralytics spells them), indexed by class id.
pub const NAMES: [&str; 80] = [
    "person",
    "bicycle",
    "car",
    "motorcycle",
    "airplane",
    "bus",
    "train",
    "truck",
    "boat",
    "traffic light",
    "fire hydrant",
    "stop sign",
    "parking meter",
    "bench",
    "bird",
    "cat",
    "dog",
    "horse",
    "sheep",
    "cow",
    "elephant",
    "bear",
    "zebra",
    "giraffe",
    "backpack",
    "umbrella",
    "handbag",
    "tie",
    "suitcase",
    "frisbee",
    "skis",
    "snowboard",
    "sports ball",
    "kite",
    "baseball bat",
    "baseball glove",
    "skateboard",
    "surfboard",
    "tennis racket",
    "bottle",
    "wine glass",
    "cup",
    "fork",
    "knife",
    "spoon",
    "bowl",
    "banana",
    "apple",
    "sandwich",
    "orange",
    "broccoli",
    "carrot",
    "hot dog",
    "pizza",
    "donut",
    "cake",
    "chair",
    "couch",
    "potted plant",
    "bed",
    "dining table",
    "toilet",
    "tv",
    "laptop",
    "mouse",
    "remote",
    "keyboard",
    "cell phone",
    "microwave",
    "oven",
    "toaster",
    "sink",
    "refrigerator",
    "book",
    "clock",
    "vase",
    "scissors",
    "teddy bear",
    "hair drier",
    "toothbrush",
];

/// Darknet's `coco.names` spellings of the classes that Ultralytics renamed.
const DARKNET_ALIASES: [(&str, usize); 6] = [
    ("motorbike", 3),
    ("aeroplane", 4),
    ("sofa", 57),
    ("pottedplant", 58),
    ("diningtable", 60),
    ("tvmonitor", 62),
];

/// The name of class `id` ("class 91" for an id outside COCO).
pub fn name(id: usize) -> String {
    NAMES
        .get(id)
        .map_or_else(|| format!("class {id}"), |n| (*n).to_string())
}

/// The class id of `name`: case-insensitive, `_` or `-` for a space, Darknet spellings
/// (`tvmonitor`, `sofa`, …) accepted.
pub fn class_id(name: &str) -> Result<usize, DetectError> {
    let wanted: String = name
        .trim()
        .to_lowercase()
        .chars()
        .map(|c| if c == '_' || c == '-' { ' ' } else { c })
        .collect();
    if let Some(id) = NAMES.iter().position(|n| *n == wanted) {
        return Ok(id);
    }
    if let Some((_, id)) = DARKNET_ALIASES.iter().find(|(alias, _)| *alias == wanted) {
        return Ok(*id);
    }
    Err(DetectError::UnknownClass {
        name: name.to_string(),
        suggestion: closest(&wanted),
    })
}

/// The COCO name closest to `wanted` in edit distance, when it is a plausible typo.
fn closest(wanted: &str) -> Option<&'static str> {
    let (distance, best) = NAMES.iter().map(|n| (edit_distance(wanted, n), *n)).min()?;
    (distance <= 2.max(wanted.chars().count() / 4)).then_some(best)
}

fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diagonal = row[0];
        row[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let substitution = diagonal + usize::from(ca != *cb);
            diagonal = row[j + 1];
            row[j + 1] = substitution.min(row[j] + 1).min(diagonal + 1);
        }
    }
    row[b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_and_aliases_resolve() {
        assert_eq!(NAMES.len(), 80);
        assert_eq!(class_id("cup").unwrap(), 41);
        assert_eq!(class_id(" Cup ").unwrap(), 41);
        assert_eq!(class_id("teddy_bear").unwrap(), 77);
        assert_eq!(class_id("tvmonitor").unwrap(), class_id("tv").unwrap());
        assert_eq!(class_id("sofa").unwrap(), 57);
        assert_eq!(name(0), "person");
        assert_eq!(name(79), "toothbrush");
        assert_eq!(name(91), "class 91");
    }

    #[test]
    fn unknown_name_is_an_error_with_a_suggestion() {
        let e = class_id("cupp").unwrap_err().to_string();
        assert!(
            e.contains("\"cupp\" is not a COCO class") && e.contains("did you mean \"cup\""),
            "{e}"
        );
        assert!(
            e.contains("person") && e.contains("toothbrush") && !e.contains('\n'),
            "{e}"
        );
        let e = class_id("spaceship").unwrap_err().to_string();
        assert!(!e.contains("did you mean"), "{e}");
    }
}
