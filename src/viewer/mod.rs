//! What the tracker sees, for a person: the left image with the model's outline, the
//! pose in 3D and the figures over time, logged to Rerun (feature `rerun`,
//! docs/viewer.md).
//!
//! [`outline`] and [`thumbnail`] are plain geometry and pixels; the rest logs (with the
//! feature only): `sink` opens the recording (a file or a running viewer), `scene` holds
//! the entities and what is drawn on them, `layout` how the viewer arranges them, `live`
//! follows the running service (`photopose viewer`) and `search` a one-shot search
//! (`photopose estimate --rerun`).

pub mod outline;
pub mod thumbnail;

#[cfg(feature = "rerun")]
pub mod layout;
#[cfg(feature = "rerun")]
pub mod live;
#[cfg(feature = "rerun")]
pub mod scene;
#[cfg(feature = "rerun")]
pub mod search;
#[cfg(feature = "rerun")]
pub mod sink;

/// The error for a Rerun option of a build without the `rerun` feature.
pub fn unavailable(option: &str) -> anyhow::Error {
    anyhow::anyhow!("{option} needs photopose built with the rerun feature (cargo build --features rerun)")
}
