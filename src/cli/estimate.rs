//! `photopose estimate`: one-shot pose and size from one stereo frame.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context};

use crate::config::Config;
use crate::estimator::model::PhotoModel;
use crate::estimator::oneshot::{self, Prepared, Report};
use crate::estimator::settings::Mode;
use crate::vision::frame::StereoImages;

/// Estimate pose and size from one stereo frame (one-shot GA).
// `[ga]` in the help texts below names a table of the configuration file, not an item.
#[allow(rustdoc::broken_intra_doc_links)]
#[derive(clap::Args, Debug)]
pub struct EstimateArgs {
    /// Photo-model file written by `photopose model`.
    #[arg(long)]
    pub model: PathBuf,
    /// Side-by-side stereo frame (left eye in the left half).
    #[arg(long, conflicts_with_all = ["left", "right"])]
    pub sbs: Option<PathBuf>,
    /// Left image (with --right) instead of --sbs.
    #[arg(long, requires = "right")]
    pub left: Option<PathBuf>,
    /// Right image (with --left).
    #[arg(long, requires = "left")]
    pub right: Option<PathBuf>,
    /// Configuration file (default: the built-in config/default.toml).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Generations (default: [ga] generations).
    #[arg(long)]
    pub generations: Option<usize>,
    /// RNG seed (default: [ga] seed); the same seed gives the same result.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Write the result as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write a side-by-side picture with the best model projected on both eyes.
    #[arg(long)]
    pub overlay: Option<PathBuf>,
    /// Record the search in Rerun: the best individual of every generation and the
    /// pyramid levels (feature `rerun`).
    #[arg(long, value_name = "FILE.rrd")]
    pub rerun: Option<PathBuf>,
}

/// Runs one estimate and prints (or writes) its result.
pub fn run(args: &EstimateArgs) -> anyhow::Result<()> {
    if args.rerun.is_some() && !cfg!(feature = "rerun") {
        return Err(crate::viewer::unavailable("--rerun"));
    }
    let config = Config::load(args.config.as_deref())?;
    let model = PhotoModel::load(&args.model)?;
    let images = match (&args.sbs, &args.left, &args.right) {
        (Some(sbs), None, None) => StereoImages::load_sbs(sbs)?,
        (None, Some(l), Some(r)) => StereoImages::load_pair(l, r)?,
        _ => bail!("give the frame as --sbs FRAME or as --left L --right R"),
    };
    let generations = args.generations.unwrap_or(config.ga.generations);
    if generations == 0 {
        bail!("--generations must be at least 1");
    }
    let seed = args.seed.unwrap_or(config.ga.seed);
    let bar = super::progress_bar(generations as u64, "generations");
    let start = Instant::now();
    let frame = match (&args.sbs, &args.left) {
        (Some(f), _) | (None, Some(f)) => f.display().to_string(),
        (None, None) => String::new(),
    };
    let prepared = Prepared::new(&model, &images, &config).with_context(|| format!("frame {frame}"))?;
    let progress = &mut search_progress(&bar, &config);
    let outcome = match &args.rerun {
        #[cfg(feature = "rerun")]
        Some(path) => logged_search(path, &model, &images, &prepared, &config, generations, seed, progress)?,
        // Without the feature `--rerun` was refused above.
        _ => oneshot::search(&prepared, &config, generations, seed, progress),
    };
    bar.finish_and_clear();
    let elapsed = start.elapsed().as_secs_f64();
    print!("{}", oneshot::table(&model, &outcome));
    let searches = match outcome.searches {
        1 => String::new(),
        n => format!("{n} searches of "),
    };
    println!(
        "mode {:?}, {searches}{} generations, {} evaluations in {:.3} s; F_L {:.4}, F_R {:.4} (pose of the model in the hand frame)",
        config.ga.mode, outcome.generations, outcome.evaluations, elapsed, outcome.fitness.left, outcome.fitness.right
    );
    let v = &outcome.verdict;
    println!(
        "{}: confidence {:.2} (left–right correlation {:.3}, correlation with the photo {:.3}, sharpness {:.3}, tilt resolution {:.2} px)",
        if v.found {
            "found"
        } else {
            "NOT found: do not act on this pose"
        },
        v.confidence,
        v.texture.stereo,
        v.texture.structure,
        v.sharpness,
        v.tilt_px
    );
    if let Some(path) = &args.json {
        let text = serde_json::to_string_pretty(&Report::new(&model, &outcome))?;
        std::fs::write(path, text + "\n").map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))?;
        println!("wrote {}", path.display());
    }
    if let Some(path) = &args.overlay {
        let picture = crate::cli::report::overlay::draw(
            &images,
            &prepared.scorer,
            &prepared.levels[0].rig,
            &model,
            &outcome.best,
        );
        picture
            .save(path)
            .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))?;
        println!("wrote {}", path.display());
    }
    Ok(())
}

/// The progress callback of a search on `bar`: the generation count of each search, and
/// which search it is when the verdict sends the robust mode searching again (each
/// starts again from generation 0).
fn search_progress<'b>(bar: &'b indicatif::ProgressBar, config: &Config) -> impl FnMut(usize) + 'b {
    let searches = match config.ga.mode {
        Mode::Robust => config.robust.retries + 1,
        Mode::Paper => 1,
    };
    let (mut search, mut last) = (1, 0);
    move |g: usize| {
        if g < last {
            search += 1;
            bar.set_message(format!("search {search} of up to {searches}: generations"));
        }
        last = g;
        bar.set_position(g as u64);
    }
}

/// [`oneshot::search`] recorded generation by generation into the Rerun file `path`.
#[cfg(feature = "rerun")]
#[allow(clippy::too_many_arguments)]
fn logged_search(
    path: &std::path::Path,
    model: &PhotoModel,
    images: &StereoImages,
    prepared: &Prepared,
    config: &Config,
    generations: usize,
    seed: u64,
    progress: &mut dyn FnMut(usize),
) -> anyhow::Result<crate::estimator::ga::Outcome> {
    use crate::viewer::search::SearchLog;
    use crate::viewer::sink::{finish, Sink};
    let rec = Sink::Save(path.to_path_buf()).open("photopose-estimate")?;
    let rigs = prepared.levels.iter().map(|l| l.rig.clone()).collect();
    let log = SearchLog::new(&rec, model, &config.left_from_hand, images, rigs)?;
    let observer = |g: &crate::estimator::ga::observe::Generation| {
        if let Err(e) = log.generation(g) {
            tracing::warn!("rerun: generation {}: {e:#}", g.generation);
        }
    };
    let outcome = oneshot::search_observed(prepared, config, generations, seed, progress, Some(&observer));
    // After every search: the last generation of the last one.
    log.result(&outcome.best, outcome.fitness.f, outcome.generations * outcome.searches)?;
    finish(&rec);
    println!("wrote {}", path.display());
    Ok(outcome)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_progress_bar_names_each_retry() {
        let bar = indicatif::ProgressBar::hidden();
        bar.set_message("generations");
        let config = Config::load(None).expect("defaults");
        let mut progress = search_progress(&bar, &config);
        (0..=1000).for_each(&mut progress);
        assert_eq!(bar.message(), "generations");
        assert_eq!(bar.position(), 1000);
        progress(3);
        assert_eq!(bar.message(), "search 2 of up to 6: generations");
        assert_eq!(bar.position(), 3);
        (4..=1000).chain([0]).for_each(&mut progress);
        assert_eq!(bar.message(), "search 3 of up to 6: generations");
    }
}
