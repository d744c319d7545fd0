//! photopose: the 6-DoF pose and size of an object seen by a ZED 2i stereo camera,
//! found from one ordinary photo of an object of the same category with the variable
//! photo-model method (Tian & Wang, Sensors 2023).
//!
//! The folders follow the data: [`capture`] (synthetic camera, replay, ZED 2i) publishes
//! frames over the [`transport`]; the [`estimator`] (photo-model, fitness, GA, one-shot
//! and tracking) turns them into poses, which the transport carries to the [`client`]
//! (pose client and servo law). Below them sit [`camera`] geometry (calibration,
//! intrinsics, the stereo rig) and [`vision`] (colour, frames, lookup images). [`render`]
//! is the synthetic camera, [`detect`] finds the object in the photo, [`config`]
//! assembles each domain's settings, [`cli`] holds the `photopose` commands, and
//! [`viewer`] logs what the tracker sees to Rerun; `bridge` (feature `zenoh`) publishes
//! the poses to ROS 2 over Zenoh.

#[cfg(feature = "zenoh")]
pub mod bridge;
pub mod camera;
pub mod capture;
pub mod cli;
pub mod client;
pub mod config;
pub mod detect;
pub mod estimator;
pub mod render;
pub mod transport;
pub mod viewer;
pub mod vision;
