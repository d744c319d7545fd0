//! The ROS 2 bridge (feature `zenoh`, `photopose bridge`, docs/ros2.md): reads the pose
//! sets from iceoryx2 and publishes each object's pose and status on Zenoh exactly as a
//! ROS 2 node on `rmw_zenoh_cpp` (Jazzy, Kilted) would.
//!
//! [`cdr`] serialises, [`msgs`] lays out the two message types, [`names`] holds
//! rmw_zenoh's key expressions, tokens and attachment, [`clock`] maps monotonic to real
//! time, [`session`] opens Zenoh, [`topics`] declares the publishers and [`run`] is the loop.

pub mod cdr;
pub mod clock;
pub mod msgs;
pub mod names;
pub mod run;
pub mod session;
pub mod topics;

pub use run::{run, Counts, Options};
