//! The real-time service as separate processes: `photopose capture`, `estimator`,
//! `controller` and `demo` talk over iceoryx2; these tests subscribe to
//! `photopose/poses` and `photopose/truth` like any client would, in Rust and through
//! the Python client `tools/pose_client.py`. They share the service names, so they run
//! one at a time ([`process::serial`]).

// Test code: a failed unwrap is a failed test.
#![allow(clippy::unwrap_used)]

#[path = "../common/mod.rs"]
mod common;
mod process;

mod access;
mod bad_frames;
mod demo;
mod latency;
mod objects;
mod pipeline;
mod python_client;
mod realtime;
mod restarts;
