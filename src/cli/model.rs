//! `photopose model`: build a photo-model from a photo and a box, given with `--box` or
//! found by the YOLO detector (cargo feature `detect`).

use std::path::PathBuf;

use anyhow::{bail, Context};
use image::RgbImage;

use crate::config::Config;
use crate::detect::{coco, Detection};
use crate::estimator::model::{DetectionRecord, PhotoModel};
use crate::vision::frame::load_rgb;

/// Build a photo-model from a photo and the object's box.
#[derive(clap::Args, Debug)]
pub struct ModelArgs {
    /// The photo (PNG or JPEG) of an object of the target's category.
    #[arg(long)]
    pub photo: PathBuf,
    /// The object's box in photo pixels: x,y,w,h with (x, y) its top-left corner.
    /// Without it the detector finds the box (build with `--features detect`).
    #[arg(long = "box", value_name = "X,Y,W,H")]
    pub bbox: Option<String>,
    /// Detection: the COCO class to take (e.g. cup); default the best detection of any class.
    #[arg(long, value_name = "NAME")]
    pub class: Option<String>,
    /// Detection: the minimum score, 0–1 (default `[detect] min_score`).
    #[arg(long, value_name = "S")]
    pub min_score: Option<f32>,
    /// Also write the photo with the box and the sampling points drawn on it (PNG).
    #[arg(long, value_name = "OUT.png")]
    pub overlay: Option<PathBuf>,
    /// Output model file (JSON).
    #[arg(short = 'o', long)]
    pub output: PathBuf,
    /// Configuration file (default: the built-in config/default.toml).
    #[arg(long)]
    pub config: Option<PathBuf>,
}

/// Parses `x,y,w,h`.
pub fn parse_box(text: &str) -> anyhow::Result<[i64; 4]> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    if parts.len() != 4 {
        bail!("--box {text:?}: expected four integers x,y,w,h");
    }
    let mut b = [0i64; 4];
    for (v, p) in b.iter_mut().zip(&parts) {
        *v = p
            .parse()
            .with_context(|| format!("--box {text:?}: {p:?} is not an integer"))?;
    }
    Ok(b)
}

/// Where the model's box comes from.
enum BoxSource {
    Given([i64; 4]),
    Detect { class: Option<usize>, min_score: f32 },
}

/// Builds the photo-model and writes it (and its overlay).
pub fn run(args: &ModelArgs) -> anyhow::Result<()> {
    let config = Config::load(args.config.as_deref())?;
    let source = match &args.bbox {
        Some(text) => BoxSource::Given(parse_box(text)?),
        None => detection_request(args, &config)?,
    };
    let photo = load_rgb(&args.photo)?;
    let (bbox, detection) = match source {
        BoxSource::Given(b) => (b, None),
        BoxSource::Detect { class, min_score } => {
            let d = detect_object(args, &config, &photo, class, min_score)?;
            (d.rect.pixel_box(photo.width(), photo.height()), Some(d))
        }
    };
    let mut model = PhotoModel::build(&photo, &args.photo, bbox, &config.model, &config.fitness.classes())?;
    model.detection = detection.map(|d| {
        let round = |v: f32| (v as f64 * 100.0).round() / 100.0;
        DetectionRecord {
            class: d.class_name(),
            score: (d.score as f64 * 1e4).round() / 1e4,
            bbox: d.rect.xywh().map(round),
        }
    });
    model.save(&args.output)?;
    println!(
        "wrote {}: box {},{},{},{} ({}x{} px), step {:.2} px, {} inner + {} outer points, mean hue {:.1} ({})",
        args.output.display(),
        model.bbox.x,
        model.bbox.y,
        model.bbox.w,
        model.bbox.h,
        model.l_p,
        model.b_p,
        model.step_px,
        model.inner.len(),
        model.outer.len(),
        model.mean_hue,
        model.center_class
    );
    if let Some(path) = &args.overlay {
        crate::cli::report::overlay::draw_model(&photo, &model)
            .save(path)
            .with_context(|| format!("cannot write {}", path.display()))?;
        println!("wrote {}", path.display());
    }
    Ok(())
}

/// The class id (if any) and minimum score of a detection, checked before anything runs.
fn detection_request(args: &ModelArgs, config: &Config) -> anyhow::Result<BoxSource> {
    let class = args.class.as_deref().map(coco::class_id).transpose()?;
    let min_score = args.min_score.unwrap_or(config.detect.min_score);
    if !(min_score > 0.0 && min_score <= 1.0) {
        bail!("--min-score {min_score}: must lie in (0, 1]");
    }
    Ok(BoxSource::Detect { class, min_score })
}

/// Runs the detector on the photo and picks the object.
#[cfg(feature = "detect")]
fn detect_object(
    args: &ModelArgs,
    config: &Config,
    photo: &RgbImage,
    class: Option<usize>,
    min_score: f32,
) -> anyhow::Result<Detection> {
    let start = std::time::Instant::now();
    let mut detector = crate::detect::Detector::new(&config.detect)?;
    let loaded = start.elapsed();
    let start = std::time::Instant::now();
    let detections = detector.detect(photo, min_score)?;
    let ran = start.elapsed();
    let chosen = crate::detect::choose(&detections, class, &args.photo, min_score)?;
    let [x, y, w, h] = chosen.rect.xywh();
    let (iw, ih) = detector.input_size();
    println!(
        "detected {} (score {:.3}) at {x:.1},{y:.1},{w:.1},{h:.1} in {}: {} detection(s), {iw}x{ih} input, {:.0} ms (model loaded in {:.0} ms)",
        chosen.class_name(),
        chosen.score,
        args.photo.display(),
        detections.list.len(),
        ran.as_secs_f64() * 1e3,
        loaded.as_secs_f64() * 1e3
    );
    Ok(chosen)
}

/// Without the detector only `--box` gives the box.
#[cfg(not(feature = "detect"))]
fn detect_object(
    _args: &ModelArgs,
    _config: &Config,
    _photo: &RgbImage,
    _class: Option<usize>,
    _min_score: f32,
) -> anyhow::Result<Detection> {
    bail!(
        "no --box given and this photopose was built without the detector: rebuild with `--features detect` (and run tools/setup-detect), or pass --box x,y,w,h"
    )
}
