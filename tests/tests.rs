//! photopose integration tests: one binary, a module per area; fixtures are found
//! through `CARGO_MANIFEST_DIR` (`common::repo`, `common::data`).

// Test code: a failed unwrap is a failed test.
#![allow(clippy::unwrap_used)]

mod accuracy;
mod cli;
mod common;
mod detect;
mod generalisation;
mod robustness;
mod scenes;
mod sequences;
mod suite;
mod tracking;
mod zed;
