//! Shared helpers for the integration tests: finding the real data and the model.
#![allow(dead_code)]

use std::path::PathBuf;

pub mod cli;
pub mod disk_cache;
pub mod feature_cache;
pub mod map_files;
pub mod phase_statistics;
pub mod pose_graph_problems;
pub mod rng;
pub mod sensor_runs;
pub mod synthetic_ba;
pub mod synthetic_slam;
pub mod temp_dir;

use spslam::features::{
    default_model_path, ExtractorConfig, GrayImage, Precision, SuperPointExtractor,
};

/// True when running under CI, where missing data is a failure, not a skip.
pub fn under_ci() -> bool {
    std::env::var("CI")
        .map(|v| v == "true" || v == "1")
        .unwrap_or(false)
}

/// Fails under CI; elsewhere prints that the test is skipped.
pub fn missing(test: &str, what: &str) {
    if under_ci() {
        panic!("{test}: {what} is missing and CI=true; run `make setup` and provide ../shared/data or SPSLAM_DATA");
    }
    eprintln!("SKIPPED {test}: {what} is missing (set SPSLAM_DATA, run `make setup`)");
}

/// Where the shared data should be: `SPSLAM_DATA`, else `../shared/data` beside the checkout.
pub fn shared_data_root() -> PathBuf {
    std::env::var_os("SPSLAM_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data"))
}

/// The folder of evo's test trajectories, or `None` after [`missing`].
pub fn evo_data(test: &str) -> Option<PathBuf> {
    let dir = shared_data_root().join("trajectories/evo_test_data");
    if dir.join("KITTI_00_gt.txt").is_file() {
        Some(dir)
    } else {
        missing(
            test,
            &format!("evo's test trajectories ({})", dir.display()),
        );
        None
    }
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

/// The shared data folder with the KITTI excerpt, or `None` after [`missing`].
pub fn data_dir(test: &str) -> Option<PathBuf> {
    let dir = shared_data_root();
    if dir.join("kitti/sequences/06/image_0/000000.png").is_file() {
        Some(dir)
    } else {
        missing(test, &format!("the shared data ({})", dir.display()));
        None
    }
}

/// True when both exported models (fp32 and int8) exist (else skip / fail as above).
pub fn model_available(test: &str) -> bool {
    for path in [default_model_path(), Precision::Int8.default_model_path()] {
        if !path.is_file() {
            missing(test, &format!("the SuperPoint model ({})", path.display()));
            return false;
        }
    }
    true
}

/// Data folder and model both present.
pub fn setup(test: &str) -> Option<PathBuf> {
    let dir = data_dir(test)?;
    model_available(test).then_some(dir)
}

/// An extractor with the given config, panicking with the error's text.
pub fn extractor(config: ExtractorConfig) -> SuperPointExtractor {
    SuperPointExtractor::new(config).unwrap_or_else(|e| panic!("cannot create the extractor: {e}"))
}

/// [`extractor`] behind the process-wide feature cache
/// ([`feature_cache::CachedExtractor`]): for runs with local mapping inline
/// that see the same images again.
pub fn cached_extractor(
    config: ExtractorConfig,
) -> feature_cache::CachedExtractor<SuperPointExtractor> {
    let tag = format!("{config:?}");
    feature_cache::CachedExtractor::new(extractor(config), tag)
}

/// Loads an image, panicking with the error's text.
pub fn load(path: PathBuf) -> GrayImage {
    GrayImage::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

/// KITTI 06 left (camera 0) or right (camera 1) frame `i`.
pub fn kitti_frame(data: &std::path::Path, camera: usize, i: usize) -> GrayImage {
    load(data.join(format!("kitti/sequences/06/image_{camera}/{i:06}.png")))
}

/// The EuRoC excerpt's cam0 images, sorted by timestamp.
pub fn euroc_cam0_paths(data: &std::path::Path) -> Vec<PathBuf> {
    let dir = data.join("euroc/V1_01_easy_first95/mav0/cam0/data");
    let mut paths: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "png"))
        .collect();
    paths.sort();
    paths
}

/// Mutual nearest neighbours by L2 distance between two descriptor blocks.
pub fn mutual_nearest_neighbours(a: &[f32], b: &[f32], dim: usize) -> Vec<(usize, usize)> {
    let (na, nb) = (a.len() / dim, b.len() / dim);
    let dist = |i: usize, j: usize| -> f32 {
        a[i * dim..(i + 1) * dim]
            .iter()
            .zip(&b[j * dim..(j + 1) * dim])
            .map(|(x, y)| (x - y) * (x - y))
            .sum()
    };
    let best = |n_from: usize, n_to: usize, d: &dyn Fn(usize, usize) -> f32| -> Vec<usize> {
        (0..n_from)
            .map(|i| {
                (0..n_to)
                    .min_by(|&p, &q| d(i, p).total_cmp(&d(i, q)))
                    .unwrap_or(usize::MAX)
            })
            .collect()
    };
    let ab = best(na, nb, &dist);
    let ba = best(nb, na, &|j, i| dist(i, j));
    ab.iter()
        .enumerate()
        .filter(|&(i, &j)| j != usize::MAX && ba[j] == i)
        .map(|(i, &j)| (i, j))
        .collect()
}

/// Indices of the frames in `records` that were not tracked.
pub fn untracked(records: &[spslam::system::FrameRecord]) -> Vec<usize> {
    records
        .iter()
        .filter(|r| r.state != spslam::tracking::TrackingState::Ok)
        .map(|r| r.index)
        .collect()
}

/// Switches loop closing on with the default codebook for extractor `config`
/// (`SPSLAM_CODEBOOK`, else `models/vlad_k64.spvlad` for int8 and
/// `models/vlad_k64_fp32.spvlad` for fp32), as `spslam run` does.
pub fn enable_loop_closing(slam: &mut spslam::system::SlamSystem, config: &ExtractorConfig) {
    let path = spslam::place::default_codebook_for(config);
    let codebook = spslam::place::Codebook::load_for(&path, config)
        .unwrap_or_else(|e| panic!("codebook {}: {e}", path.display()));
    slam.enable_loop_closing(
        std::sync::Arc::new(codebook.vlad),
        spslam::loop_closing::LoopThresholds::default(),
    )
    .unwrap_or_else(|e| panic!("{e}"));
}
