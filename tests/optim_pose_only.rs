//! Pose-only optimisation on seeded synthetic scenes (`common::synthetic_ba`:
//! KITTI camera, pixel noise σ = 0.5 px × 1.2^octave with the matching
//! information). The frame is keyframe 5 of a 10-keyframe scene with 2,000
//! points (~1,400 correspondences), the points are the ground truth.
//!
//! Tolerances:
//! - from a start perturbed by σ 3° and 5 cm per axis, the pose ends within
//!   0.02° and 5 mm of the ground truth (mono, stereo and mixed; seen: ≤ 0.006°, ≤ 1.5 mm);
//! - with 20 % planted outliers (20–100 px) every planted outlier is
//!   flagged, at most 5 % of the clean correspondences are, and the pose
//!   meets the same tolerances;
//! - the inlier flags are exactly the χ² test at the returned pose;
//! - fewer than 3 correspondences or a non-finite input is a typed error;
//!   fewer than 10 runs a single round.

mod common;

use common::synthetic_ba::{perturb, pose_error, Rng, Scene, SceneSpec};
use spslam::optim::pose_only::{optimise_pose, PoseOnlyConfig, PoseOnlyResult};
use spslam::optim::reprojection::Observation;
use spslam::optim::{LieGroup, OptimError};

fn scene(stereo_fraction: f64, outlier_fraction: f64, seed: u64) -> Scene {
    Scene::new(&SceneSpec {
        points: 2000,
        pixel_noise: 0.5,
        stereo_fraction,
        outlier_fraction,
        seed,
        ..SceneSpec::default()
    })
}

fn run(scene: &Scene, seed: u64) -> (PoseOnlyResult, Vec<bool>) {
    let frame = 5;
    let (correspondences, planted) = scene.correspondences(frame);
    let start = perturb(&mut Rng::new(seed), &scene.poses[frame], 3.0, 0.05);
    let result = optimise_pose(
        &scene.camera,
        &start,
        &correspondences,
        &PoseOnlyConfig::default(),
    )
    .expect("optimises");
    let (rot, trans) = pose_error(&result.pose, &scene.poses[frame]);
    eprintln!(
        "{} correspondences, {} inliers, rounds {}, error {rot:.4}° {trans:.4} m",
        correspondences.len(),
        result.inlier_count,
        result.rounds_run
    );
    assert!(rot < 0.02, "rotation error {rot}°");
    assert!(trans < 0.005, "translation error {trans} m");
    // Flags are the χ² test at the returned pose.
    for (i, c) in correspondences.iter().enumerate() {
        let p_cam = result.pose.transform_point(&c.point);
        let inlier = p_cam.z > 0.0 && result.chi2[i] <= c.observation.chi2_threshold();
        assert_eq!(result.inliers[i], inlier, "flag {i}");
    }
    assert_eq!(
        result.inlier_count,
        result.inliers.iter().filter(|&&a| a).count()
    );
    (result, planted)
}

#[test]
fn mixed_converges_from_a_noisy_start() {
    let (result, _) = run(&scene(0.5, 0.0, 1), 2);
    assert_eq!(result.rounds_run, 4);
}

#[test]
fn mono_only_converges() {
    run(&scene(0.0, 0.0, 3), 4);
}

#[test]
fn stereo_only_converges() {
    run(&scene(1.0, 0.0, 5), 6);
}

#[test]
fn planted_outliers_are_flagged() {
    let scene = scene(0.5, 0.2, 7);
    let (result, planted) = run(&scene, 8);
    let missed = planted
        .iter()
        .zip(&result.inliers)
        .filter(|(&p, &inlier)| p && inlier)
        .count();
    let clean = planted.iter().filter(|&&p| !p).count();
    let false_alarms = planted
        .iter()
        .zip(&result.inliers)
        .filter(|(&p, &inlier)| !p && !inlier)
        .count();
    eprintln!(
        "planted {} missed {missed} false alarms {false_alarms} of {clean}",
        planted.len() - clean
    );
    assert_eq!(missed, 0);
    assert!((false_alarms as f64) <= 0.05 * clean as f64);
}

#[test]
fn too_few_correspondences_is_an_error() {
    let scene = scene(0.5, 0.0, 9);
    let (correspondences, _) = scene.correspondences(5);
    let err = optimise_pose(
        &scene.camera,
        &scene.poses[5],
        &correspondences[..2],
        &PoseOnlyConfig::default(),
    )
    .expect_err("fails");
    assert_eq!(
        err,
        OptimError::InsufficientCorrespondences {
            required: 3,
            actual: 2
        }
    );
    let result = optimise_pose(
        &scene.camera,
        &scene.poses[5],
        &correspondences[..6],
        &PoseOnlyConfig::default(),
    )
    .expect("six are enough");
    assert_eq!(result.rounds_run, 1, "fewer than 10 run one round");
}

#[test]
fn non_finite_input_is_an_error() {
    let scene = scene(0.5, 0.0, 10);
    let (mut correspondences, _) = scene.correspondences(5);
    let config = PoseOnlyConfig::default();
    correspondences[4].point.z = f64::NAN;
    assert_eq!(
        optimise_pose(&scene.camera, &scene.poses[5], &correspondences, &config),
        Err(OptimError::InvalidValue {
            what: "point",
            index: 4
        })
    );
    let (mut correspondences, _) = scene.correspondences(5);
    correspondences[7].observation = Observation::stereo(1.0, f64::NAN, 0.0, 1.0);
    assert_eq!(
        optimise_pose(&scene.camera, &scene.poses[5], &correspondences, &config),
        Err(OptimError::InvalidValue {
            what: "observation",
            index: 7
        })
    );
    let mut pose = scene.poses[5];
    pose.translation.y = f64::INFINITY;
    let (correspondences, _) = scene.correspondences(5);
    assert_eq!(
        optimise_pose(&scene.camera, &pose, &correspondences, &config),
        Err(OptimError::InvalidValue {
            what: "pose",
            index: 0
        })
    );
}
