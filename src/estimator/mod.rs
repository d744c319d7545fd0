//! From a photo and stereo frames to a pose and size: the photo-[`model`], a candidate
//! [`pose`], the stereo [`fitness`], the [`ga`] that searches, the [`oneshot`] estimate of
//! one frame and [`tracking`] across frames (on the GA's [`ga::live`] population, kept
//! from frame to frame) of one or several [`objects`], on the fitness [`workers`] with
//! the [`realtime`] options of the estimator process; the [`exposure`] gains that keep a
//! tracked object's colours under changing light. [`settings`] holds each estimator
//! setting and its validation.
//! Nothing here knows the wire format.

pub mod exposure;
pub mod fitness;
pub mod ga;
pub mod model;
pub mod objects;
pub mod oneshot;
pub mod pose;
pub mod realtime;
pub mod settings;
pub mod tracking;
pub mod verify;
pub mod workers;
