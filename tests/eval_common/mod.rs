//! Shared helpers of the `eval_*` tests: finding evo's test trajectories.
#![allow(dead_code)]

use std::path::PathBuf;

/// The folder of evo's test trajectories (`$SPSLAM_DATA` or `../shared/data`,
/// then `trajectories/evo_test_data`). When missing: panics under `CI=true`,
/// else prints `SKIPPED …` and returns `None`.
pub fn evo_data(test: &str) -> Option<PathBuf> {
    let root = std::env::var_os("SPSLAM_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data"));
    let dir = root.join("trajectories/evo_test_data");
    if dir.join("KITTI_00_gt.txt").is_file() {
        return Some(dir);
    }
    let ci = std::env::var("CI")
        .map(|v| v == "true" || v == "1")
        .unwrap_or(false);
    if ci {
        panic!("{test}: {} is missing and CI=true", dir.display());
    }
    eprintln!(
        "SKIPPED {test}: {} is missing (set SPSLAM_DATA)",
        dir.display()
    );
    None
}

/// Asserts that `actual` equals `expected` to 4 significant digits
/// (relative difference below 5e-4).
pub fn assert_sig4(what: &str, actual: f64, expected: f64) {
    let rel = ((actual - expected) / expected).abs();
    assert!(
        rel < 5e-4,
        "{what}: {actual} vs expected {expected} (relative {rel:e})"
    );
}
