//! The viewer's layout (a Rerun blueprint sent with the recording): the left image and
//! the 3D hand frame beside the time series, truth and estimate in one plot per axis.

use rerun::blueprint::components::{PanelState, PlayState};
use rerun::blueprint::{
    Blueprint, BlueprintActivation, BlueprintPanel, ContainerLike, Horizontal, SelectionPanel, Spatial2DView,
    Spatial3DView, TimePanel, TimeSeriesView, Vertical,
};
use rerun::{RecordingStream, RecordingStreamResult};

use crate::viewer::scene::{FRAME_TIMELINE, IMAGE};

/// A time series view named `name` of the entities `query` matches.
fn series(name: &str, query: &str) -> ContainerLike {
    TimeSeriesView::new(name).with_contents([query]).into()
}

/// The images on the left, `plots` stacked on the right, panels folded away, the time
/// line `timeline` selected and following the newest data.
fn send(
    rec: &RecordingStream,
    images: Vec<ContainerLike>,
    plots: Vec<ContainerLike>,
    timeline: &str,
) -> RecordingStreamResult<()> {
    let root =
        Horizontal::new([Vertical::new(images).into(), Vertical::new(plots).into()]).with_column_shares([3.0, 2.0]);
    Blueprint::new(root)
        .with_blueprint_panel(BlueprintPanel::new().with_state(PanelState::Collapsed))
        .with_selection_panel(SelectionPanel::new().with_state(PanelState::Collapsed))
        .with_time_panel(
            TimePanel::new()
                .with_timeline(timeline)
                .with_state(PanelState::Collapsed)
                .with_play_state(PlayState::Following),
        )
        .send(rec, BlueprintActivation::default())
}

/// The left camera and the hand frame in 3D.
fn views() -> Vec<ContainerLike> {
    vec![
        Spatial2DView::new("left camera")
            .with_origin(format!("/{IMAGE}"))
            .into(),
        Spatial3DView::new("hand frame (mm)").with_origin("/world").into(),
    ]
}

/// The layout of `photopose viewer`.
pub fn live(rec: &RecordingStream) -> RecordingStreamResult<()> {
    let plots = vec![
        series("x [mm]", "/series/x/**"),
        series("y [mm]", "/series/y/**"),
        series("z [mm]", "/series/z/**"),
        series("fitness F", "/series/fitness"),
        series("status (0 tracking, 1 searching, 2 lost)", "/series/status"),
        series("capture → pose [ms]", "/series/latency_ms"),
        series("frames dropped", "/series/dropped"),
    ];
    send(rec, views(), plots, FRAME_TIMELINE)
}

/// The layout of `photopose estimate --rerun`, with `levels` pyramid levels.
pub fn search(rec: &RecordingStream, levels: usize) -> RecordingStreamResult<()> {
    let mut images = views();
    images.extend((1..levels).map(|l| {
        let level = format!("/pyramid/level_{l}");
        ContainerLike::from(Spatial2DView::new(format!("level {l}")).with_origin(level))
    }));
    let plots = vec![
        series("fitness F (full resolution)", "/ga/fitness"),
        series("score", "/ga/score"),
        series("pyramid level", "/ga/level"),
        series("x [mm]", "/series/x/**"),
        series("y [mm]", "/series/y/**"),
        series("z [mm]", "/series/z/**"),
        series("size L, B [mm]", "/series/size/**"),
    ];
    send(rec, images, plots, crate::viewer::search::GENERATION_TIMELINE)
}
