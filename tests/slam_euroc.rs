//! Stereo SLAM with SuperPoint + ANMS on the EuRoC V1_01 excerpt (95
//! frames, the drone nearly still before take-off), after rectification:
//! every frame tracked, the estimated positions within 2 cm of each other,
//! and the SE3-aligned ATE against the Vicon ground truth below 1 cm.

mod common;

use opencv::imgcodecs;
use spslam::camera::CameraRig;
use spslam::dataset::{EurocSequence, StereoRectifier};
use spslam::eval::{evaluate, read_euroc, EvalOptions, Pairing, Trajectory};
use spslam::features::{ExtractorConfig, GrayImage};
use spslam::settings::SlamSettings;
use spslam::system::SlamSystem;
use spslam::tracking::Frontend;

fn read_gray(path: &std::path::Path) -> opencv::core::Mat {
    let text = path.to_str().unwrap_or_else(|| panic!("non-UTF-8 path"));
    imgcodecs::imread(text, imgcodecs::IMREAD_GRAYSCALE).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn euroc_v1_01_excerpt_superpoint_anms() {
    let Some(data) = common::setup("euroc_v1_01_excerpt_superpoint_anms") else {
        return;
    };
    let seq = EurocSequence::open(data.join("euroc/V1_01_easy_first95"))
        .unwrap_or_else(|e| panic!("{e}"));
    let rectifier =
        StereoRectifier::from_euroc(seq.cam0(), seq.cam1()).unwrap_or_else(|e| panic!("{e}"));
    let mut settings = SlamSettings::rectified_stereo(
        rectifier.fx(),
        rectifier.fy(),
        rectifier.cx(),
        rectifier.cy(),
        rectifier.baseline(),
    );
    settings.camera.fps = 20.0;
    let load = |i: usize| {
        let f = &seq.frames()[i];
        let pair = rectifier
            .rectify(&read_gray(&f.left), &read_gray(&f.right))
            .unwrap_or_else(|e| panic!("{e}"));
        let image = |m| GrayImage::from_mat(m).unwrap_or_else(|e| panic!("{e}"));
        (image(&pair.left), image(&pair.right))
    };
    let (first, _) = load(0);
    let rig = CameraRig::from_settings(&settings, first.width(), first.height())
        .unwrap_or_else(|e| panic!("{e}"));
    let sp = || Box::new(common::extractor(ExtractorConfig::default()));
    let mut slam = SlamSystem::new(rig, Frontend::new(sp(), sp(), &rig));
    if let Some(mapper) = slam.mapper_mut() {
        mapper.check_invariants = true;
    }
    // The excerpt never revisits a place: loop closing must accept nothing.
    common::enable_loop_closing(&mut slam, &ExtractorConfig::default());
    for (i, f) in seq.frames().iter().enumerate() {
        let (l, r) = load(i);
        slam.process(i, f.timestamp, l.view(), r.view())
            .unwrap_or_else(|e| panic!("frame {i}: {e}"));
    }
    let lost: Vec<usize> = common::untracked(slam.records());
    let poses = slam.trajectory().unwrap_or_else(|e| panic!("{e}"));
    let positions: Vec<_> = poses.iter().map(|(_, p)| p.translation).collect();
    let spread = positions
        .iter()
        .flat_map(|a| positions.iter().map(move |b| (a - b).norm()))
        .fold(0.0f64, f64::max);
    let estimate = Trajectory::new(
        poses.iter().map(|(t, _)| *t).collect(),
        poses.iter().map(|(_, p)| p.to_isometry()).collect(),
    );
    let gt_path = seq
        .ground_truth_path()
        .unwrap_or_else(|| panic!("no ground truth"));
    let gt = read_euroc(&gt_path).unwrap_or_else(|e| panic!("{e}"));
    let report = evaluate(
        &gt,
        &estimate,
        &EvalOptions {
            pairing: Pairing::ByTimestamp {
                max_diff: 0.01,
                one_to_one: true,
            },
            ..EvalOptions::default()
        },
    )
    .unwrap_or_else(|e| panic!("{e}"));
    eprintln!(
        "EuRoC V1_01 excerpt: spread {spread:.4} m, ATE se3 {:.4} m over {} poses, lost {lost:?}",
        report.ate.se3_rmse, report.matched_poses
    );
    assert!(lost.is_empty(), "frames not tracked: {lost:?}");
    eprintln!(
        "EuRoC excerpt: {} loops accepted, {} candidates rejected after the descriptor stage",
        slam.loops().len(),
        slam.rejected_loops().len()
    );
    assert!(slam.loops().is_empty(), "false loops: {:?}", slam.loops());
    assert!(spread <= 0.02, "positions spread over {spread} m");
    assert!(report.ate.se3_rmse <= 0.01, "ATE {} m", report.ate.se3_rmse);
}
