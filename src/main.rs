//! The `photopose` binary: subcommands over the library.

use std::process::ExitCode;

use clap::{Parser, Subcommand};
use photopose::cli;

#[derive(Parser, Debug)]
#[command(
    name = "photopose",
    version,
    about = "6-DoF pose and size of an object from one photo and a ZED 2i stereo camera"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Build a photo-model from a photo and the object's box.
    Model(cli::model::ModelArgs),
    /// Estimate pose and size from one stereo frame (one-shot GA).
    Estimate(cli::estimate::EstimateArgs),
    /// Render a synthetic stereo frame of a photo card in a cluttered scene.
    Render(cli::render::RenderArgs),
    /// Publish stereo frames on photopose/stereo_frames (synthetic camera or replay).
    Capture(cli::capture::CaptureArgs),
    /// Track the model in the frame stream and publish poses on photopose/poses.
    Estimator(cli::estimator::EstimatorArgs),
    /// Example robot client: visual servoing on photopose/poses (commands logged).
    Controller(cli::controller::ControllerArgs),
    /// Run capture, estimator and controller on the synthetic camera; summary and plot.
    Demo(cli::demo::DemoArgs),
    /// Measure the fitness kernel, a one-shot estimate and the tracking loop.
    Bench(cli::bench::BenchArgs),
    /// Measure transport, estimation and end-to-end latency of the running service.
    Latency(cli::latency::LatencyArgs),
    /// Log frames, poses and truth of the running service to Rerun (file or viewer).
    #[cfg(feature = "rerun")]
    Viewer(cli::viewer::ViewerArgs),
    /// Publish each object's pose and status to ROS 2 over Zenoh (rmw_zenoh).
    #[cfg(feature = "zenoh")]
    Bridge(cli::bridge::BridgeArgs),
}

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into()))
        .with_writer(std::io::stderr)
        // Colours for a terminal only: logs written to files stay plain text.
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Model(a) => cli::model::run(a),
        Command::Estimate(a) => cli::estimate::run(a),
        Command::Render(a) => cli::render::run(a),
        Command::Capture(a) => cli::capture::run(a),
        Command::Estimator(a) => cli::estimator::run(a),
        Command::Controller(a) => cli::controller::run(a),
        Command::Demo(a) => cli::demo::run(a),
        Command::Bench(a) => cli::bench::run(a),
        Command::Latency(a) => cli::latency::run(a),
        #[cfg(feature = "rerun")]
        Command::Viewer(a) => cli::viewer::run(a),
        #[cfg(feature = "zenoh")]
        Command::Bridge(a) => cli::bridge::run(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
