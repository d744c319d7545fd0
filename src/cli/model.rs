//! `photopose model`: build a photo-model from a photo and a box.

use std::path::PathBuf;

use anyhow::{bail, Context};

use crate::config::Config;
use crate::frame::load_rgb;
use crate::model::PhotoModel;

#[derive(clap::Args, Debug)]
pub struct ModelArgs {
    /// The photo (PNG or JPEG) of an object of the target's category.
    #[arg(long)]
    pub photo: PathBuf,
    /// The object's box in photo pixels: x,y,w,h with (x, y) its top-left corner.
    #[arg(long = "box", value_name = "X,Y,W,H")]
    pub bbox: String,
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

pub fn run(args: &ModelArgs) -> anyhow::Result<()> {
    let config = Config::load(args.config.as_deref())?;
    let bbox = parse_box(&args.bbox)?;
    let photo = load_rgb(&args.photo)?;
    let model = PhotoModel::build(&photo, &args.photo, bbox, &config.model, &config.fitness.classes())?;
    model.save(&args.output)?;
    println!(
        "wrote {}: box {}x{} px, step {:.2} px, {} inner + {} outer points, mean hue {:.1} ({})",
        args.output.display(),
        model.l_p,
        model.b_p,
        model.step_px,
        model.inner.len(),
        model.outer.len(),
        model.mean_hue,
        model.center_class
    );
    Ok(())
}
