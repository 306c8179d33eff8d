//! The benchmark frames shared by the extractor benches: KITTI 06's first
//! left frame (1226×370) and the first EuRoC V1_01 cam0 frame (752×480).

use std::path::{Path, PathBuf};

/// The data folder: `SPSLAM_DATA`, else `../shared/data` next to the crate.
pub fn data_dir() -> PathBuf {
    std::env::var_os("SPSLAM_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data"))
}

/// The benchmark frames: (group name, path); `None` when a frame is missing.
pub fn frames(data: &Path) -> Vec<(&'static str, Option<PathBuf>)> {
    let kitti = data.join("kitti/sequences/06/image_0/000000.png");
    let euroc_dir = data.join("euroc/V1_01_easy_first95/mav0/cam0/data");
    let euroc = std::fs::read_dir(&euroc_dir).ok().and_then(|d| {
        let mut pngs: Vec<PathBuf> = d
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|e| e == "png"))
            .collect();
        pngs.sort();
        pngs.into_iter().next()
    });
    vec![
        ("kitti_1226x370", kitti.is_file().then_some(kitti)),
        ("euroc_752x480", euroc),
    ]
}
