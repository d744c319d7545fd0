//! `photopose render`: renders a synthetic side-by-side ZED frame from a scene file and
//! optionally writes the ground-truth pose as JSON; or writes a whole scenario (a take
//! of a robot cell) as a recorded sequence.

use std::path::{Path, PathBuf};

use anyhow::Context;

use crate::capture::scenario::film;
use crate::capture::scenario::{InView, Scenario, SCORED_SHARE};
use crate::render::{self, SceneSpec};

/// Render a synthetic stereo frame of a photo card, or a scenario as a sequence.
#[derive(clap::Args, Debug)]
pub struct RenderArgs {
    /// Scene description (TOML).
    #[arg(long, value_name = "SCENE.toml", required_unless_present = "scenario")]
    pub scene: Option<PathBuf>,
    /// Instead of a scene: write this scenario (sweep, sweep-60fps, yuyv, light, occlude,
    /// leave, approach; docs/tracking-sequences.md) as a recorded sequence into the
    /// `--output` directory, for `photopose capture --source replay:DIR`.
    #[arg(long, value_name = "NAME", conflicts_with_all = ["scene", "truth"])]
    pub scenario: Option<String>,
    /// Output side-by-side frame: PNG, or JPEG when the name ends in `.jpg`/`.jpeg`; with
    /// `--scenario`, the sequence's directory (new, or without a recording).
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
    let scene = match (&args.scene, &args.scenario) {
        (_, Some(name)) => return write_scenario(name, &args.output, &config),
        (Some(scene), None) => scene,
        (None, None) => anyhow::bail!("give --scene SCENE.toml or --scenario NAME"),
    };
    let spec = SceneSpec::load(scene)?;
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

/// Writes scenario `name` into `dir` as a recorded sequence, with a progress bar; its
/// photos are read under the current directory (the repository's root).
fn write_scenario(name: &str, dir: &Path, config: &crate::config::Config) -> anyhow::Result<()> {
    let scenario = Scenario::named(name).map_err(anyhow::Error::msg)?;
    let visible = record_scenario(&scenario, dir, config)?;
    let count = |seen: &dyn Fn(&InView) -> f64| visible.iter().filter(|v| seen(v) >= SCORED_SHARE).count();
    println!(
        "wrote {} frames of scenario {name} ({} fps, {} of them with ≥ 60 % of the card in view, {} in both eyes' view) to {}; play it with `photopose capture --source replay:{}`",
        visible.len(),
        scenario.fps,
        count(&|v| v.left),
        count(&|v| v.both_eyes),
        dir.display(),
        dir.display()
    );
    Ok(())
}

/// Renders `scenario` into `dir` with a progress bar: each frame's shares of the card in
/// view.
pub fn record_scenario(scenario: &Scenario, dir: &Path, config: &crate::config::Config) -> anyhow::Result<Vec<InView>> {
    let bar = super::progress_bar(scenario.frames() as u64, &format!("rendering {}", scenario.name));
    let visible = film::record(scenario, Path::new("."), config, dir, |n| bar.set_position(n as u64));
    bar.finish_and_clear();
    visible.map_err(anyhow::Error::msg)
}

fn create_parent(path: &Path) -> anyhow::Result<()> {
    match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => {
            std::fs::create_dir_all(dir).with_context(|| format!("cannot create directory {}", dir.display()))
        }
        _ => Ok(()),
    }
}
