//! Helpers shared by the test binaries (`tests.rs`, `service.rs`).

use std::path::{Path, PathBuf};

/// A fresh, empty scratch directory `target/test-scratch/NAME`.
pub fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("target/test-scratch")
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}
