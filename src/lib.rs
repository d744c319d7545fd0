//! photopose: the 6-DoF pose and size of an object seen by a ZED 2i stereo camera,
//! found from one ordinary photo of an object of the same category with the variable
//! photo-model method (Tian & Wang, Sensors 2023).
//!
//! Data flows: [`calibration`] + [`config`] → [`camera`] rig; [`model`] samples the photo;
//! [`frame`] prepares each stereo frame's colour data and [`lookup`] packs it for the
//! fitness; [`fitness`] scores a candidate
//! [`pose`]; [`ga`] searches; [`estimate`] runs it end to end; [`render`] is the
//! synthetic camera; [`overlay`] draws the result; [`detect`] finds the object in the
//! photo when no box is given.

pub mod calibration;
pub mod camera;
pub mod capture;
pub mod cli;
pub mod client;
pub mod color;
pub mod config;
pub mod detect;
pub mod estimate;
pub mod fitness;
pub mod frame;
pub mod ga;
pub mod ipc;
pub mod lookup;
pub mod messages;
pub mod model;
pub mod overlay;
pub mod plot;
pub mod pose;
pub mod realtime;
pub mod render;
pub mod stats;
pub mod tracking;
pub mod workers;
