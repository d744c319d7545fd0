//! The `photopose` command line: one module per subcommand.

pub mod bench;
#[cfg(feature = "zenoh")]
pub mod bridge;
pub mod capture;
pub mod controller;
pub mod demo;
pub mod estimate;
pub mod estimator;
pub mod latency;
pub mod model;
pub mod render;
pub mod report;
pub mod skips;
#[cfg(feature = "rerun")]
pub mod viewer;

use std::io::IsTerminal;

use indicatif::{ProgressBar, ProgressStyle};

use crate::config::Config;
use crate::estimator::model::PhotoModel;
use crate::render::SceneSpec;
use crate::vision::frame::load_rgb;

/// A progress bar on an interactive terminal, hidden otherwise (logs, CI, pipes).
pub fn progress_bar(len: u64, what: &str) -> ProgressBar {
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(len);
    if let Ok(style) = ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} ({elapsed})") {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_message(what.to_string());
    bar
}

/// The photo-model of a scene's photo and box (the synthetic camera's target).
pub fn scene_model(spec: &SceneSpec, config: &Config) -> anyhow::Result<PhotoModel> {
    let photo = load_rgb(&spec.photo)?;
    let [x, y, w, h] = spec.box_px.map(i64::from);
    Ok(PhotoModel::build(
        &photo,
        &spec.photo,
        [x, y, w, h],
        &config.model,
        &config.fitness.classes(),
    )?)
}
