//! Helpers shared by the test binaries (`integration`, `service`, `alloc`) and the
//! benches: files of the repository, scratch directories, and frames as a ZED sends them.
//! Each binary uses a part of them.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use photopose::vision::color::rgb_row_to_yuyv;

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

/// A side-by-side RGB8 frame (both eyes `eye_width` pixels wide, rows back to back)
/// encoded as the ZED sends it: YUYV, two bytes a pixel.
pub fn yuyv_from_rgb(rgb: &[u8], eye_width: usize) -> Vec<u8> {
    let row = 2 * eye_width;
    assert_eq!(rgb.len() % (3 * row), 0, "not whole rows of {row} RGB pixels");
    let mut yuyv = vec![0u8; rgb.len() / 3 * 2];
    for (src, dst) in rgb.chunks_exact(3 * row).zip(yuyv.chunks_exact_mut(2 * row)) {
        rgb_row_to_yuyv(src, dst);
    }
    yuyv
}
