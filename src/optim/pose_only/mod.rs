//! Pose-only (motion-only) optimisation: ORB-SLAM3's
//! `Optimizer::PoseOptimization` on the shared reprojection model.
//!
//! The camera pose `T_cw` is refined against fixed 3-D points in rounds
//! ([`PoseOnlyConfig`]): each round runs Levenberg–Marquardt on the 6×6
//! normal equations over the current inliers, then reclassifies *every*
//! observation by its χ² at the new pose (5.991 mono, 7.815 stereo), so an
//! outlier can become an inlier again. The Huber kernel (δ = √threshold) is
//! used in all rounds but the last. As in ORB-SLAM3, every round restarts
//! from the initial pose (only the inlier set carries over), and with fewer
//! than 10 correspondences only the first round runs.
//!
//! Differences from ORB-SLAM3, on purpose: a point behind the camera
//! (depth ≤ 0) is an outlier whatever its χ²; a round with fewer than 3
//! inliers keeps the pose of the previous round instead of optimising an
//! under-determined system.
//!
//! Fewer than 3 correspondences (ORB-SLAM3's own minimum) is an error:
//! [`OptimError::InsufficientCorrespondences`](crate::optim::OptimError::InsufficientCorrespondences).

mod refine;
mod rounds;

use nalgebra::Vector3;

pub use rounds::optimise_pose;

use super::reprojection::Observation;
use super::Se3;

/// A fixed world point and its observation in the frame being optimised.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseCorrespondence {
    /// The world point (not optimised).
    pub point: Vector3<f64>,
    /// Its observation in the frame.
    pub observation: Observation,
}

/// Settings of [`optimise_pose`]; the defaults are ORB-SLAM3's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseOnlyConfig {
    /// Outlier-reclassification rounds (4).
    pub rounds: usize,
    /// LM iterations per round (10).
    pub iterations_per_round: usize,
    /// How many leading rounds use the Huber kernel (3: dropped in the last round).
    pub robust_rounds: usize,
    /// Fewer correspondences than this is an error (3).
    pub min_correspondences: usize,
    /// With fewer correspondences than this only the first round runs (10).
    pub min_for_more_rounds: usize,
    /// Restart every round from the initial pose, as ORB-SLAM3 does (true).
    pub restart_each_round: bool,
    /// Stop a round when an accepted step lowers the cost by less than this fraction (1e-10).
    pub relative_cost_tolerance: f64,
}

impl Default for PoseOnlyConfig {
    fn default() -> Self {
        Self {
            rounds: 4,
            iterations_per_round: 10,
            robust_rounds: 3,
            min_correspondences: 3,
            min_for_more_rounds: 10,
            restart_each_round: true,
            relative_cost_tolerance: 1e-10,
        }
    }
}

/// The outcome of [`optimise_pose`].
#[derive(Debug, Clone, PartialEq)]
pub struct PoseOnlyResult {
    /// The refined `T_cw`.
    pub pose: Se3,
    /// Per correspondence: true when it passed the last χ² test.
    pub inliers: Vec<bool>,
    /// How many are inliers.
    pub inlier_count: usize,
    /// Per correspondence: χ² at the refined pose (no kernel).
    pub chi2: Vec<f64>,
    /// Sum of the inliers' χ².
    pub inlier_chi2_sum: f64,
    /// Rounds actually run.
    pub rounds_run: usize,
}
