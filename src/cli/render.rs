//! `photopose render`: renders a synthetic side-by-side ZED frame from a scene file and
//! optionally writes the ground-truth pose as JSON.

use std::path::{Path, PathBuf};

use anyhow::Context;

use crate::render::{self, SceneSpec};

/// Render a synthetic stereo frame of a photo card.
#[derive(clap::Args, Debug)]
pub struct RenderArgs {
    /// Scene description (TOML).
    #[arg(long, value_name = "SCENE.toml")]
    pub scene: PathBuf,
    /// Output side-by-side frame: PNG, or JPEG when the name ends in `.jpg`/`.jpeg`.
    #[arg(short, long, value_name = "FRAME.png")]
    pub output: PathBuf,
    /// Also write the true pose and size (hand frame) as JSON.
    #[arg(long, value_name = "TRUTH.json")]
    pub truth: Option<PathBuf>,
    /// Configuration file (calibration, left_from_hand); built-in defaults otherwise.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
}

/// Runs the `render` command.
pub fn run(args: &RenderArgs) -> anyhow::Result<()> {
    let config = crate::config::Config::load(args.config.as_deref())?;
    let spec = SceneSpec::load(&args.scene)?;
    let rig = config.calibration.rig(spec.resolution)?;
    let scene = spec.build(&config.left_from_hand)?;
    let frame = render::render(&rig, &config.left_from_hand, &scene);

    create_parent(&args.output)?;
    let format = match image::ImageFormat::from_path(&args.output) {
        Ok(image::ImageFormat::Jpeg) => image::ImageFormat::Jpeg,
        _ => image::ImageFormat::Png,
    };
    frame
        .save_with_format(&args.output, format)
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    let mut written = format!(
        "wrote {} ({}×{}, {})",
        args.output.display(),
        frame.width(),
        frame.height(),
        spec.resolution
    );
    if let Some(truth) = &args.truth {
        let json = render::scene::truth_json(&spec.hand_from_model, spec.size_mm);
        create_parent(truth)?;
        let text = serde_json::to_string_pretty(&json)?;
        std::fs::write(truth, text + "\n").with_context(|| format!("cannot write {}", truth.display()))?;
        written.push_str(&format!(" and truth {}", truth.display()));
    }
    println!("{written}");
    Ok(())
}

fn create_parent(path: &Path) -> anyhow::Result<()> {
    match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => {
            std::fs::create_dir_all(dir).with_context(|| format!("cannot create directory {}", dir.display()))
        }
        _ => Ok(()),
    }
}
