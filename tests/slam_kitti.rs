//! Stereo SLAM with SuperPoint on the KITTI 06 excerpt (51 frames), far
//! points kept (ORB-SLAM3's stereo points beyond `ThDepth`, observed with
//! their bearing only: `map::observation`), with what `spslam run` uses by
//! default (the int8 network on `DEFAULT_SUPERPOINT_LEVELS` pyramid
//! levels): every frame tracked, and the int8 run's ATE within 10 % of the
//! fp32 network's on the same levels (70 % for the 7-bit-weight int8 model
//! of CPUs without VNNI). The ATE and drift bounds are regression bounds
//! from the measured values (session 40, AMD EPYC with VNNI: int8 0.0372 m
//! / 0.91 %, fp32 0.0374 m; the 7-bit model 0.0568 m; `EVALUATION.md`,
//! "Far keypoints with their bearing only").

mod common;

use spslam::camera::CameraRig;
use spslam::dataset::KittiSequence;
use spslam::eval::{evaluate, read_kitti, EvalOptions, Pairing, Trajectory};
use spslam::features::{GrayImage, Precision};
use spslam::settings::{ExtractorSettings, SlamSettings};
use spslam::system::SlamSystem;
use spslam::tracking::Frontend;

/// What one run gave: ATE SE3 (m), final drift (% of the path), frames not tracked.
struct KittiRun {
    ate_m: f64,
    drift_pct: f64,
    lost: Vec<usize>,
}

fn run_kitti(data: &std::path::Path, precision: Option<Precision>) -> KittiRun {
    let seq = KittiSequence::open(data.join("kitti"), "06").unwrap_or_else(|e| panic!("{e}"));
    let mut settings = SlamSettings::from_file(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/settings/KITTI04-12.yaml"
    ))
    .unwrap_or_else(|e| panic!("{e}"));
    if let Some(precision) = precision {
        settings.extractor.precision = precision;
    }
    let first = GrayImage::load(&seq.frames()[0].left).unwrap_or_else(|e| panic!("{e}"));
    let rig = CameraRig::from_settings(&settings, first.width(), first.height())
        .unwrap_or_else(|e| panic!("{e}"));
    // What `spslam run` builds: SuperPoint on the settings' SuperPoint
    // levels, kd-tree ANMS, every stereo depth kept (far points tracked
    // as in ORB-SLAM3).
    let config = settings
        .extractor
        .superpoint_config(settings.extractor.superpoint_levels_for(false), 1);
    let sp = || Box::new(common::extractor(config.clone()));
    let mut slam = SlamSystem::new(rig, Frontend::new(sp(), sp(), &rig));
    if let Some(mapper) = slam.mapper_mut() {
        mapper.check_invariants = true;
    }
    // The excerpt never revisits a place: loop closing must accept nothing.
    common::enable_loop_closing(&mut slam, &config);
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
    eprintln!(
        "KITTI excerpt: {} loops accepted, {} candidates rejected after the descriptor stage",
        slam.loops().len(),
        slam.rejected_loops().len()
    );
    assert!(slam.loops().is_empty(), "false loops: {:?}", slam.loops());
    let run = KittiRun {
        ate_m: report.ate.se3_rmse,
        drift_pct: 100.0 * drift / report.path_length_m,
        lost: common::untracked(slam.records()),
    };
    eprintln!(
        "KITTI 06 excerpt, {} on {} levels: ATE se3 {:.4} m, final drift {drift:.3} m ({:.2} %), lost {:?}",
        config.precision, config.n_levels, run.ate_m, run.drift_pct, run.lost
    );
    run
}

#[test]
fn kitti_06_excerpt_superpoint_defaults_and_int8_vs_fp32() {
    let Some(data) = common::setup("kitti_06_excerpt_superpoint") else {
        return;
    };
    // The int8 model this CPU loads: 8-bit weights with VNNI, 7-bit
    // weights without (ONNX Runtime's sums saturate there; see
    // `features::int8_sums_saturate`). The 7-bit model follows fp32 less
    // closely (score correlation 0.963 against 0.989): measured with
    // `SPSLAM_MODEL_INT8=models/superpoint_int8_avx2.onnx` (its outputs do
    // not depend on the kernels): ATE 0.0568 m, fp32 0.0374 m (+52 %;
    // +19 % when far keypoints were stereo observations, at 0.096 and
    // 0.081 m); the 8-bit model on VNNI: 0.0372 m (−1 %).
    let seven_bit = Precision::Int8
        .default_model_path()
        .ends_with(Precision::Int8.model_file(true));
    let (ate_bound_m, int8_ratio) = if seven_bit { (0.07, 1.7) } else { (0.05, 1.1) };
    let default = run_kitti(&data, None);
    assert!(
        default.lost.is_empty(),
        "frames not tracked: {:?}",
        default.lost
    );
    assert!(
        default.ate_m <= ate_bound_m,
        "ATE {} m (7-bit int8 model: {seven_bit})",
        default.ate_m
    );
    assert!(default.drift_pct <= 1.2, "drift {} %", default.drift_pct);

    let int8 = if ExtractorSettings::default().precision == Precision::Int8 {
        default
    } else {
        run_kitti(&data, Some(Precision::Int8))
    };
    let fp32 = run_kitti(&data, Some(Precision::Fp32));
    assert!(int8.lost.is_empty() && fp32.lost.is_empty());
    // The bound: int8 within 10 % of fp32 (3 mm slack for another
    // machine's kernels; measured −1 %); 70 % for the 7-bit model
    // (measured +52 %).
    assert!(
        int8.ate_m <= int8_ratio * fp32.ate_m + 0.003,
        "int8 ATE {} m vs fp32 {} m (7-bit int8 model: {seven_bit})",
        int8.ate_m,
        fp32.ate_m
    );
}
