//! Local bundle adjustment: ORB-SLAM's `Optimizer::LocalBundleAdjustment` on
//! the shared reprojection model, with Levenberg–Marquardt over the Schur
//! complement of the points.
//!
//! # Algorithm
//! - **Stage 1**: LM with the Huber kernel (δ = √5.991 mono, √7.815 stereo)
//!   over every observation, [`LocalBaConfig::first_stage_iterations`] (5).
//! - **Outliers**: observations with χ² above 5.991 / 7.815, or whose point
//!   lies behind the camera, are excluded.
//! - **Stage 2**: LM over the remaining observations without the kernel
//!   (ORB-SLAM2's second pass; [`LocalBaConfig::second_stage_iterations`], 10;
//!   0 gives ORB-SLAM3 v1.0's single stage).
//! - **Report**: the test is applied again at the final estimate; stage-1
//!   outliers stay outliers (as in ORB-SLAM, whose excluded edges keep their
//!   stage-1 error). [`LocalBaReport::outliers`] lists them for erasure.
//!
//! Each LM iteration linearises once (per point `H_pp = V`, `b_p`, per
//! observation `W`, per free pose `H_cc`, `b_c`), then, for a damping `μ`
//! (Nielsen's update, `H + μI`), forms the reduced camera system
//! `(H_cc + μI − W V⁻¹ Wᵀ) δc = −b_c + W V⁻¹ b_p` over the free poses,
//! solves it by Cholesky (dense or sparse, below), back-substitutes
//! `δp = V⁻¹(−b_p − Wᵀ δc)` and accepts the step when the gain ratio is
//! positive (up to 10 dampings tried per iteration). The per-point passes run on
//! [`LocalBaConfig::threads`] scoped threads over contiguous point chunks.
//! A stage stops when the relative cost decrease falls below
//! [`LocalBaConfig::relative_cost_tolerance`], the step below
//! [`LocalBaConfig::relative_step_tolerance`], or at its iteration limit.
//!
//! # Dense and sparse reduced camera system
//! - **Dense** ([`ReducedSystemSolver::Dense`]): each point chunk
//!   accumulates its own dense `6k×6k` part of `S`; the parts are summed
//!   and factorised by nalgebra's dense Cholesky. `O(k²)` memory per chunk
//!   and `O(k³)` time: right for local windows of a few tens of keyframes.
//! - **Sparse** ([`ReducedSystemSolver::Sparse`]): `S`'s block pattern is
//!   the diagonal plus the free pose pairs that share a point. It is built
//!   once per bundle adjustment with the `BlockPattern<6>` of the
//!   crate-internal `optim::sparse` module, shared with the pose graph
//!   (AMD-ordered lower-triangle block CSC; `sparse_schur.rs`). Each chunk
//!   scatters its `−W V⁻¹ Wᵀ` blocks into a value array of that pattern
//!   (each pair of a point's observations finds its block in a per-point
//!   table built with the pattern: one indexed load), the arrays are
//!   summed, `H_cc + μD` is added on the diagonal blocks, and faer's
//!   supernodal sparse Cholesky (symbolic analysis once per bundle
//!   adjustment, numeric factorisation per damping) solves. Memory and time
//!   follow the covisibility (a chain of keyframes: linear in `k`), which
//!   makes global bundle adjustment over hundreds to thousands of
//!   keyframes practical.
//! - [`ReducedSystemSolver::Auto`] (the default) takes the sparse path from
//!   [`LocalBaConfig::sparse_min_free_poses`] (40) free poses on (the
//!   measured crossover). The two paths assemble the same `−Σ W V⁻¹ Wᵀ` bit
//!   for bit; they differ in the factorisation's rounding (and which
//!   triangle of `H_cc` they read), and their results agree to ~1e-14.
//!
//! # Gauge
//! Fixed poses are never written (they stay bit-identical). When no pose is
//! fixed, the first pose (index 0) is fixed and reported in
//! [`LocalBaReport::gauge_fixed_pose`]. With monocular observations only and
//! a single fixed pose the scale stays free; the damping keeps the system
//! regular and the scale drifts only as far as the data allow. Points seen
//! only by fixed poses are still optimised.

mod blocks;
mod chunk;
mod config;
mod layout;
mod linearise;
mod outliers;
mod parallel;
mod problem;
mod report;
mod schur;
mod solver;
mod sparse_schur;
mod step;

pub use config::{LocalBaConfig, ReducedSystemSolver};
pub use problem::{BaObservation, BundleProblem};
pub use report::{LocalBaReport, StageReport, Termination};

use std::sync::atomic::AtomicBool;

use chunk::pose_matrices;
use layout::Layout;
use outliers::deactivate_outliers;
use solver::{Solver, StageSettings, State};
use sparse_schur::ReducedPattern;

use super::OptimError;

/// Runs local bundle adjustment on `problem`, updating its free poses and
/// its points in place (see the module docs).
///
/// Errors (the problem is left untouched): [`OptimError::NoObservations`],
/// [`OptimError::PoseIndexOutOfRange`], [`OptimError::PointIndexOutOfRange`],
/// [`OptimError::FixedFlagsLength`], [`OptimError::InvalidValue`] for a
/// non-finite input, [`OptimError::NonFiniteInitialCost`] when a point
/// sits at zero depth, and on the sparse path
/// [`OptimError::SymbolicFactorisation`] when the pattern's analysis fails
/// (out of memory).
pub fn local_bundle_adjustment(
    problem: &mut BundleProblem,
    config: &LocalBaConfig,
) -> Result<LocalBaReport, OptimError> {
    local_bundle_adjustment_abortable(problem, config, None)
}

/// [`local_bundle_adjustment`] that stops early when `abort` is raised
/// (ORB-SLAM3's `mbAbortBA`, raised when tracking queues a new keyframe):
/// the running stage returns after its current LM iteration with
/// [`Termination::Aborted`], a stage not yet started is skipped, and the
/// problem receives the best state reached. Outliers are classified at
/// that state, as after a complete run.
pub fn local_bundle_adjustment_abortable(
    problem: &mut BundleProblem,
    config: &LocalBaConfig,
    abort: Option<&AtomicBool>,
) -> Result<LocalBaReport, OptimError> {
    problem.validate()?;
    let mut fixed = problem.fixed.clone();
    let gauge_fixed_pose = if fixed.iter().any(|&f| f) {
        None
    } else {
        fixed[0] = true;
        Some(0)
    };
    let layout = Layout::new(problem, &fixed, config.worker_threads());
    let free_poses = layout.free_poses.len();
    let reduced_pattern = if free_poses > 0 && config.uses_sparse_solver(free_poses) {
        Some(ReducedPattern::new(&layout)?)
    } else {
        None
    };
    let mut solver = Solver::new(&problem.camera, &layout, reduced_pattern.as_ref(), config)?;
    let mut poses = problem.poses.clone();
    let mut points = problem.points.clone();
    let mut active = vec![true; layout.observations.len()];
    let mut state = State {
        poses: &mut poses,
        points: &mut points,
    };
    let first_stage = solver.run_stage(
        &mut state,
        &StageSettings {
            active: &active,
            robust: true,
            iterations: config.first_stage_iterations,
            abort,
        },
    )?;
    let mut matrices = Vec::new();
    pose_matrices(state.poses, &mut matrices);
    deactivate_outliers(
        &problem.camera,
        &layout,
        &matrices,
        state.points,
        &mut active,
    );
    let second_stage = solver.run_stage(
        &mut state,
        &StageSettings {
            active: &active,
            robust: config.robust_second_stage,
            iterations: config.second_stage_iterations,
            abort,
        },
    )?;
    pose_matrices(state.poses, &mut matrices);
    let inlier_chi2_sum = deactivate_outliers(
        &problem.camera,
        &layout,
        &matrices,
        state.points,
        &mut active,
    );
    let mut outliers: Vec<usize> = layout
        .observations
        .iter()
        .zip(&active)
        .filter(|(_, &a)| !a)
        .map(|(o, _)| o.original as usize)
        .collect();
    outliers.sort_unstable();
    problem.poses = poses;
    problem.points = points;
    Ok(LocalBaReport {
        first_stage,
        second_stage,
        outliers,
        inlier_chi2_sum,
        gauge_fixed_pose,
    })
}
