//! The `photopose` command line: one module per subcommand.

pub mod capture;
pub mod controller;
pub mod demo;
pub mod estimate;
pub mod estimator;
pub mod model;
pub mod render;

use std::io::IsTerminal;

use indicatif::{ProgressBar, ProgressStyle};

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
