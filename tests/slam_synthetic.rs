//! Stereo SLAM on a synthetic straight street generated into a temporary
//! folder: every frame must be tracked and the trajectory must match the
//! exact ground truth.

use std::path::{Path, PathBuf};

use spslam::dataset::synthetic::{
    write_sequence, SceneName, SyntheticConfig, SyntheticSequence, WriteOptions,
};
use spslam::dataset::KittiSequence;
use spslam::eval::{read_kitti, Trajectory};
use spslam::features::{GrayImage, OrbConfig, OrbExtractor};
use spslam::settings::SlamSettings;
use spslam::tracking::{StereoFrontend, StereoRig, StereoSlam, TrackingState};

/// Frames in the synthetic test (10 m/s at 10 fps: 50 m).
const FRAMES: usize = 50;
/// ATE (SE3-aligned RMSE) tolerance on the synthetic street, metres.
const ATE_TOLERANCE_M: f64 = 0.10;

fn temp_root(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("spslam_{name}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn run_orb_slam(root: &Path) -> (StereoSlam, Trajectory) {
    let seq = KittiSequence::open(root, "00").unwrap_or_else(|e| panic!("{e}"));
    let c = seq.calibration();
    let settings = SlamSettings::rectified_stereo(c.fx, c.fy, c.cx, c.cy, c.baseline);
    let first = GrayImage::load(&seq.frames()[0].left).unwrap_or_else(|e| panic!("{e}"));
    let rig = StereoRig::from_settings(&settings, first.width(), first.height())
        .unwrap_or_else(|e| panic!("{e}"));
    let orb =
        || Box::new(OrbExtractor::new(OrbConfig::default()).unwrap_or_else(|e| panic!("{e}")));
    let mut slam = StereoSlam::new(rig, StereoFrontend::new(orb(), orb(), &rig));
    for (i, f) in seq.frames().iter().enumerate() {
        let l = GrayImage::load(&f.left).unwrap_or_else(|e| panic!("{e}"));
        let r = GrayImage::load(&f.right).unwrap_or_else(|e| panic!("{e}"));
        slam.process(i, f.timestamp, l.view(), r.view())
            .unwrap_or_else(|e| panic!("frame {i}: {e}"));
    }
    let poses = slam.trajectory().unwrap_or_else(|e| panic!("{e}"));
    let trajectory = Trajectory::new(
        poses.iter().map(|(t, _)| *t).collect(),
        poses.iter().map(|(_, p)| p.to_isometry()).collect(),
    );
    (slam, trajectory)
}

#[test]
#[ignore = "first version: tracking is lost after about 25 frames (issue 7); run with --ignored"]
fn synthetic_straight_street_is_tracked_throughout() {
    let root = temp_root("slam_straight");
    let mut config = SyntheticConfig::for_scene(SceneName::Straight);
    config.frames = Some(FRAMES);
    let sequence = SyntheticSequence::new(config).unwrap_or_else(|e| panic!("{e}"));
    let written = write_sequence(&sequence, &root, &WriteOptions::default(), &mut |_, _| {})
        .unwrap_or_else(|e| panic!("{e}"));
    let (slam, estimate) = run_orb_slam(&root);
    let summary = slam.summary().unwrap_or_else(|e| panic!("{e}"));
    let gt = read_kitti(&written.poses_path).unwrap_or_else(|e| panic!("{e}"));
    // A straight path is collinear, so Umeyama alignment is degenerate: both
    // trajectories start at the identity, so compare positions unaligned.
    let n = gt.len().min(estimate.len());
    let sum: f64 = (0..n)
        .map(|i| {
            (gt.poses[i].translation.vector - estimate.poses[i].translation.vector).norm_squared()
        })
        .sum();
    let rmse = (sum / n.max(1) as f64).sqrt();
    eprintln!("synthetic straight, ORB: {summary:?}");
    let lost: Vec<usize> = slam
        .records()
        .iter()
        .filter(|r| r.state != TrackingState::Ok)
        .map(|r| r.index)
        .collect();
    eprintln!("position RMSE (unaligned) {rmse:.4} m over {n} frames");
    let _ = std::fs::remove_dir_all(&root);
    assert!(lost.is_empty(), "frames not tracked: {lost:?}");
    assert!(
        rmse < ATE_TOLERANCE_M,
        "ATE {rmse} m above {ATE_TOLERANCE_M} m"
    );
}
