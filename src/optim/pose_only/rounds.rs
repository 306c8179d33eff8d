//! ORB-SLAM3's rounds of refinement and χ² reclassification.

use super::refine::RefineProblem;
use super::{PoseCorrespondence, PoseOnlyConfig, PoseOnlyResult};
use crate::optim::reprojection::{observation_chi2, PinholeStereo, PoseMatrix};
use crate::optim::{OptimError, Se3};

fn validate(
    camera: &PinholeStereo,
    initial: &Se3,
    correspondences: &[PoseCorrespondence],
    config: &PoseOnlyConfig,
) -> Result<(), OptimError> {
    if !camera.is_valid() {
        return Err(OptimError::InvalidValue {
            what: "camera",
            index: 0,
        });
    }
    let pose_finite = initial.translation.iter().all(|v| v.is_finite())
        && initial.rotation.coords.iter().all(|v| v.is_finite());
    if !pose_finite {
        return Err(OptimError::InvalidValue {
            what: "pose",
            index: 0,
        });
    }
    for (index, c) in correspondences.iter().enumerate() {
        if !c.point.iter().all(|v| v.is_finite()) {
            return Err(OptimError::InvalidValue {
                what: "point",
                index,
            });
        }
        if !c.observation.is_valid() {
            return Err(OptimError::InvalidValue {
                what: "observation",
                index,
            });
        }
    }
    let required = config.min_correspondences.max(3);
    if correspondences.len() < required {
        return Err(OptimError::InsufficientCorrespondences {
            required,
            actual: correspondences.len(),
        });
    }
    Ok(())
}

/// Refines `initial` (`T_cw`) against the fixed points of `correspondences`
/// (see the module docs for the rounds and the outlier test).
///
/// Errors: [`OptimError::InvalidValue`] for a non-finite camera, pose, point
/// or observation (or a non-positive information weight);
/// [`OptimError::InsufficientCorrespondences`] below
/// `config.min_correspondences` (at least 3).
pub fn optimise_pose(
    camera: &PinholeStereo,
    initial: &Se3,
    correspondences: &[PoseCorrespondence],
    config: &PoseOnlyConfig,
) -> Result<PoseOnlyResult, OptimError> {
    validate(camera, initial, correspondences, config)?;
    let n = correspondences.len();
    let mut inliers = vec![true; n];
    let mut chi2 = vec![0.0; n];
    let mut pose = *initial;
    let mut rounds_run = 0;
    for round in 0..config.rounds.max(1) {
        let start = if config.restart_each_round {
            *initial
        } else {
            pose
        };
        let active = inliers.iter().filter(|&&a| a).count();
        pose = if active >= 3 {
            let problem = RefineProblem {
                camera,
                correspondences,
                active: &inliers,
                robust: round < config.robust_rounds,
            };
            problem.refine(
                start,
                config.iterations_per_round,
                config.relative_cost_tolerance,
            )
        } else {
            pose
        };
        rounds_run += 1;
        classify(camera, &pose, correspondences, &mut inliers, &mut chi2);
        if n < config.min_for_more_rounds {
            break;
        }
    }
    let inlier_count = inliers.iter().filter(|&&a| a).count();
    let inlier_chi2_sum = chi2
        .iter()
        .zip(&inliers)
        .filter(|(_, &a)| a)
        .map(|(c, _)| c)
        .sum();
    Ok(PoseOnlyResult {
        pose,
        inliers,
        inlier_count,
        chi2,
        inlier_chi2_sum,
        rounds_run,
    })
}

/// Marks each correspondence an inlier when its χ² is within its threshold
/// and its point lies in front of the camera.
fn classify(
    camera: &PinholeStereo,
    pose: &Se3,
    correspondences: &[PoseCorrespondence],
    inliers: &mut [bool],
    chi2: &mut [f64],
) {
    let pm = PoseMatrix::from_se3(pose);
    for ((c, inlier), chi2) in correspondences.iter().zip(inliers).zip(chi2) {
        let p_cam = pm.transform(&c.point);
        *chi2 = observation_chi2(camera, &p_cam, &c.observation);
        *inlier = p_cam.z > 0.0 && *chi2 <= c.observation.chi2_threshold();
    }
}
