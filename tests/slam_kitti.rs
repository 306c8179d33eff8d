//! Stereo SLAM with SuperPoint on the KITTI 06 excerpt (51 frames), far
//! points kept (ORB-SLAM3's stereo points beyond `ThDepth`): every frame
//! tracked. The ATE and drift bounds are regression bounds from the
//! measured 0.058 m and 0.99 % (`EVALUATION.md`; the target of
//! 0.030 m is not met: with the paper's 20 m filter it was 0.033 m).

mod common;

use spslam::camera::StereoRig;
use spslam::dataset::KittiSequence;
use spslam::eval::{evaluate, read_kitti, EvalOptions, Pairing, Trajectory};
use spslam::features::GrayImage;
use spslam::settings::SlamSettings;
use spslam::system::StereoSlam;
use spslam::tracking::StereoFrontend;

#[test]
fn kitti_06_excerpt_superpoint() {
    let Some(data) = common::setup("kitti_06_excerpt_superpoint") else {
        return;
    };
    let seq = KittiSequence::open(data.join("kitti"), "06").unwrap_or_else(|e| panic!("{e}"));
    let settings = SlamSettings::from_file(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/settings/KITTI04-12.yaml"
    ))
    .unwrap_or_else(|e| panic!("{e}"));
    let first = GrayImage::load(&seq.frames()[0].left).unwrap_or_else(|e| panic!("{e}"));
    let rig = StereoRig::from_settings(&settings, first.width(), first.height())
        .unwrap_or_else(|e| panic!("{e}"));
    // What `spslam run` builds: SuperPoint on the settings' 8 pyramid
    // levels, kd-tree ANMS, every stereo depth kept (far points tracked
    // as in ORB-SLAM3).
    let config = settings
        .extractor
        .superpoint_config(settings.extractor.n_levels, 1);
    let sp = || Box::new(common::extractor(config.clone()));
    let mut slam = StereoSlam::new(rig, StereoFrontend::new(sp(), sp(), &rig));
    if let Some(mapper) = slam.mapper_mut() {
        mapper.check_invariants = true;
    }
    for (i, f) in seq.frames().iter().enumerate() {
        let l = GrayImage::load(&f.left).unwrap_or_else(|e| panic!("{e}"));
        let r = GrayImage::load(&f.right).unwrap_or_else(|e| panic!("{e}"));
        slam.process(i, f.timestamp, l.view(), r.view())
            .unwrap_or_else(|e| panic!("frame {i}: {e}"));
    }
    let poses = slam.trajectory().unwrap_or_else(|e| panic!("{e}"));
    let estimate = Trajectory::new(
        poses.iter().map(|(t, _)| *t).collect(),
        poses.iter().map(|(_, p)| p.to_isometry()).collect(),
    );
    let gt_path = seq
        .ground_truth_path()
        .unwrap_or_else(|| panic!("no ground truth"));
    let gt = read_kitti(&gt_path).unwrap_or_else(|e| panic!("{e}"));
    let gt = gt.select(&(0..estimate.len().min(gt.len())).collect::<Vec<_>>());
    let report = evaluate(
        &gt,
        &estimate,
        &EvalOptions {
            pairing: Pairing::ByIndex,
            ..EvalOptions::default()
        },
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let last = gt.len() - 1;
    let drift =
        (gt.poses[last].translation.vector - estimate.poses[last].translation.vector).norm();
    let drift_pct = 100.0 * drift / report.path_length_m;
    let lost: Vec<usize> = common::untracked(slam.records());
    eprintln!(
        "KITTI 06 excerpt: ATE se3 {:.4} m, final drift {drift:.3} m ({drift_pct:.2} %), lost {lost:?}",
        report.ate.se3_rmse
    );
    assert!(lost.is_empty(), "frames not tracked: {lost:?}");
    assert!(report.ate.se3_rmse <= 0.07, "ATE {} m", report.ate.se3_rmse);
    assert!(drift_pct <= 1.2, "drift {drift_pct} %");
}
