//! Solver options and the report of a run.

use crate::optim::error::OptimError;

/// Which step the solver takes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Algorithm {
    /// Undamped Gauss–Newton: `H δ = −b`; stops when a step does not lower χ².
    GaussNewton,
    /// Levenberg–Marquardt: `(H + λI) δ = −b` with Nielsen's update of `λ`
    /// (initial `λ = τ · max diag H`), rejected steps raise `λ`.
    LevenbergMarquardt,
}

/// Options of [`super::PoseGraphSolver`].
///
/// The default uses Levenberg–Marquardt, at most 100 iterations, the
/// relative χ² tolerance 1e-6 and one assembly thread: on the shared
/// 2-vCPU machine two threads were slower (`BENCHMARKS.md`); a dedicated
/// multi-core machine may set more.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseGraphOptions {
    /// Gauss–Newton or Levenberg–Marquardt.
    pub algorithm: Algorithm,
    /// Upper bound on iterations (accepted plus rejected steps).
    pub max_iterations: usize,
    /// Stop when an accepted step lowers χ² by less than this fraction.
    pub relative_chi2_tolerance: f64,
    /// Stop when χ² is at or below this (noise-free problems reach rounding).
    pub absolute_chi2_tolerance: f64,
    /// Stop when the largest entry of a step is at or below this.
    pub step_tolerance: f64,
    /// `τ` in the initial damping `λ = τ · max diag H` (LM only).
    pub initial_lambda_scale: f64,
    /// Threads assembling the normal equations (at least 1; graphs use at
    /// most one thread per 1,000 edges). The factorisation is sequential.
    pub assembly_threads: usize,
}

impl Default for PoseGraphOptions {
    fn default() -> Self {
        Self {
            algorithm: Algorithm::LevenbergMarquardt,
            max_iterations: 100,
            relative_chi2_tolerance: 1e-6,
            absolute_chi2_tolerance: 1e-20,
            step_tolerance: 1e-12,
            initial_lambda_scale: 1e-5,
            assembly_threads: 1,
        }
    }
}

impl PoseGraphOptions {
    /// Checks that every tolerance is finite and non-negative and that at
    /// least one assembly thread is asked for.
    pub fn validate(&self) -> Result<(), OptimError> {
        if self.assembly_threads == 0 {
            return Err(OptimError::InvalidOption {
                option: "assembly_threads",
                value: 0.0,
            });
        }
        for (option, value) in [
            ("relative_chi2_tolerance", self.relative_chi2_tolerance),
            ("absolute_chi2_tolerance", self.absolute_chi2_tolerance),
            ("step_tolerance", self.step_tolerance),
            ("initial_lambda_scale", self.initial_lambda_scale),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(OptimError::InvalidOption { option, value });
            }
        }
        Ok(())
    }
}

/// Why the solver stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Termination {
    /// An accepted step lowered χ² by less than the relative tolerance.
    RelativeDecrease,
    /// χ² reached the absolute tolerance.
    AbsoluteChi2,
    /// The step's largest entry fell to the step tolerance.
    SmallStep,
    /// No step lowers χ² any more (Gauss–Newton step rejected, or LM damping exhausted).
    NoDecrease,
    /// The iteration limit was reached first.
    MaxIterations,
    /// No node is free (or no edge touches a free node).
    NothingToOptimise,
}

/// One iteration of the solver.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IterationRecord {
    /// χ² at the candidate point (`NaN` when the factorisation failed).
    pub candidate_chi2: f64,
    /// The damping used (0 for Gauss–Newton).
    pub lambda: f64,
    /// Whether the step was taken.
    pub accepted: bool,
    /// Wall time of the iteration: damping, numeric factorisation, solve,
    /// update and relinearisation at the candidate.
    pub seconds: f64,
}

/// What a run did.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseGraphSummary {
    /// Iterations run (accepted and rejected).
    pub iterations: usize,
    /// χ² at the initial poses.
    pub initial_chi2: f64,
    /// χ² at the returned poses.
    pub final_chi2: f64,
    /// Why the solver stopped.
    pub termination: Termination,
    /// The node held constant to fix the gauge when none was flagged fixed.
    pub auto_fixed_node: Option<usize>,
    /// Number of nodes optimised.
    pub free_nodes: usize,
    /// Seconds of the one-off sparsity analysis and symbolic factorisation.
    pub symbolic_seconds: f64,
    /// Seconds of the initial linearisation.
    pub initial_linearisation_seconds: f64,
    /// Seconds of the whole run, symbolic analysis included.
    pub total_seconds: f64,
    /// Every iteration in order.
    pub iteration_log: Vec<IterationRecord>,
}

impl PoseGraphSummary {
    /// Mean wall time of an iteration (0 when none ran).
    pub fn mean_iteration_seconds(&self) -> f64 {
        if self.iteration_log.is_empty() {
            return 0.0;
        }
        let total: f64 = self.iteration_log.iter().map(|record| record.seconds).sum();
        total / self.iteration_log.len() as f64
    }
}
