//! Helpers shared by the test binaries (`integration`, `service`, `alloc`) and the
//! benches: files of the repository, scratch directories, and frames as a ZED sends them.
//! Each binary uses a part of them.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

/// A file or directory of the repository, `REL` relative to its root.
pub fn repo(rel: impl AsRef<Path>) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

/// A test fixture, `tests/data/REL`.
pub fn data(rel: impl AsRef<Path>) -> PathBuf {
    repo("tests/data").join(rel)
}

/// A fresh, empty scratch directory `target/test-scratch/NAME`.
pub fn scratch(name: &str) -> PathBuf {
    let dir = repo("target/test-scratch").join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}
