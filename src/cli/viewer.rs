//! `photopose viewer` (feature `rerun`): follows the running service and logs what the
//! tracker sees to Rerun, into an `.rrd` file or a running viewer (docs/viewer.md).

use std::path::PathBuf;

use anyhow::Result;

use crate::config::Config;
use crate::estimator::model::PhotoModel;
use crate::viewer::live::{self, Options};
use crate::viewer::sink::{self, Sink, DEFAULT_URL};

/// Log frames, poses and truth to Rerun.
#[derive(clap::Args, Debug)]
pub struct ViewerArgs {
    /// Write the recording to this file.
    #[arg(long, value_name = "FILE.rrd", conflicts_with = "connect")]
    pub save: Option<PathBuf>,
    /// Stream to a running Rerun viewer (default: the one `rerun` starts on this machine).
    #[arg(long, value_name = "URL", num_args = 0..=1, default_missing_value = DEFAULT_URL)]
    pub connect: Option<String>,
    /// Configuration file (`[camera]`, `[hand_eye]`); built-in defaults otherwise.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// The photo-model being tracked: its outer strip is drawn too.
    #[arg(long, value_name = "MODEL")]
    pub model: Option<PathBuf>,
    /// Images per second at most.
    #[arg(long, default_value_t = 10.0)]
    pub rate: f64,
    /// Widest logged image, pixels (the left eye is shrunk by a whole factor).
    #[arg(long, default_value_t = 480)]
    pub width: usize,
    /// Stop after this many seconds (0: run until interrupted).
    #[arg(long, default_value_t = 0.0)]
    pub seconds: f64,
}

/// Logs the service until interrupted or `--seconds` pass.
pub fn run(args: &ViewerArgs) -> Result<()> {
    // First, so that the recording's threads inherit the lower priority too.
    live::lower_priority();
    let config = Config::load(args.config.as_deref())?;
    let strip_per_length = match &args.model {
        Some(path) => {
            let model = PhotoModel::load(path)?;
            model.outer_width_px / model.l_p
        }
        None => 0.0,
    };
    let options = Options {
        rate_hz: args.rate,
        max_width: args.width,
        quality: 75,
        strip_per_length,
        seconds: args.seconds,
    };
    options.check()?;
    let sink = Sink::from_args(args.save.as_ref(), args.connect.as_ref())?;
    let rec = sink.open("photopose")?;
    crate::viewer::layout::live(&rec)?;
    let counts = live::run(&rec, &config.calibration, &config.left_from_hand, &options);
    sink::finish(&rec);
    let counts = counts?;
    println!(
        "viewer: logged {} images, {} poses, {} truths",
        counts.frames, counts.poses, counts.truths
    );
    Ok(())
}
