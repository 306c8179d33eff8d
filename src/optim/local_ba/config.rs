//! Settings of local bundle adjustment.

use crate::optim::damping::NielsenDamping;

/// How the reduced camera system `S δc = s` is factorised.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ReducedSystemSolver {
    /// Sparse from [`LocalBaConfig::sparse_min_free_poses`] free poses on,
    /// dense below (the default).
    #[default]
    Auto,
    /// Dense Cholesky of the full `6k×6k` matrix (each worker chunk holds
    /// its own `6k×6k` partial sum): fastest for a local window.
    Dense,
    /// Block-sparse Cholesky over the covisibility pattern (free pose pairs
    /// that share a point), the symbolic analysis done once per bundle
    /// adjustment: memory and time grow with the covisibility, not `k²`/`k³`
    /// (global bundle adjustment).
    Sparse,
}

/// Settings of [`super::local_bundle_adjustment`]; the defaults follow
/// ORB-SLAM's two-stage `LocalBundleAdjustment`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalBaConfig {
    /// LM iterations of the first stage, with the Huber kernel (5).
    pub first_stage_iterations: usize,
    /// LM iterations of the second stage, over the inliers of the first (10);
    /// 0 skips it (ORB-SLAM3 v1.0's single stage).
    pub second_stage_iterations: usize,
    /// Keep the Huber kernel in the second stage (false: ORB-SLAM drops it).
    pub robust_second_stage: bool,
    /// Stop when an accepted step lowers the cost by less than this fraction (1e-6).
    pub relative_cost_tolerance: f64,
    /// Stop when `|δ| ≤ tol · (|x| + tol)` (1e-10).
    pub relative_step_tolerance: f64,
    /// Initial damping `μ₀`, relative to `diag(H)` (1e-4).
    pub initial_damping: f64,
    /// Damping increases tried per iteration before stopping (g2o's 10).
    pub max_tries_per_iteration: usize,
    /// Worker threads for the per-point passes; 0 uses the available
    /// parallelism. Default 1: on the shared 2-vCPU machine a busy second
    /// core made 2 threads 2.5× slower than 1 (a scoped join waits for a
    /// preempted worker), and local mapping runs beside tracking anyway.
    /// Results are deterministic for a given value.
    pub threads: usize,
    /// Dense or sparse factorisation of the reduced camera system
    /// ([`ReducedSystemSolver::Auto`]). Both give the same result to rounding.
    pub reduced_solver: ReducedSystemSolver,
    /// With [`ReducedSystemSolver::Auto`], the sparse path is taken from this
    /// many free poses on (40: measured crossover on the 2-vCPU machine, see
    /// BENCHMARKS.md — below it the dense path is as fast or faster).
    pub sparse_min_free_poses: usize,
}

impl Default for LocalBaConfig {
    fn default() -> Self {
        Self {
            first_stage_iterations: 5,
            second_stage_iterations: 10,
            robust_second_stage: false,
            relative_cost_tolerance: 1e-6,
            relative_step_tolerance: 1e-10,
            initial_damping: NielsenDamping::DEFAULT_INITIAL_MU,
            max_tries_per_iteration: 10,
            threads: 1,
            reduced_solver: ReducedSystemSolver::Auto,
            sparse_min_free_poses: Self::DEFAULT_SPARSE_MIN_FREE_POSES,
        }
    }
}

impl LocalBaConfig {
    /// Default of [`Self::sparse_min_free_poses`].
    pub const DEFAULT_SPARSE_MIN_FREE_POSES: usize = 40;

    /// Whether a problem with `free_poses` free poses (after the gauge
    /// choice) is solved by the sparse path.
    pub fn uses_sparse_solver(&self, free_poses: usize) -> bool {
        match self.reduced_solver {
            ReducedSystemSolver::Auto => free_poses >= self.sparse_min_free_poses,
            ReducedSystemSolver::Dense => false,
            ReducedSystemSolver::Sparse => true,
        }
    }

    /// The same settings with only the first `share` (0–1) of the
    /// iterations, in order: the first stage's, then the second's (rounded
    /// to the nearest iteration). A BA interrupted after `share` of its
    /// work has done these (ORB-SLAM3's `mbAbortBA` stops g2o after its
    /// current iteration and keeps what it reached).
    pub fn with_iteration_share(self, share: f64) -> Self {
        let total = self.first_stage_iterations + self.second_stage_iterations;
        let kept = (share.clamp(0.0, 1.0) * total as f64).round() as usize;
        let first = kept.min(self.first_stage_iterations);
        Self {
            first_stage_iterations: first,
            second_stage_iterations: kept - first,
            ..self
        }
    }

    /// The number of worker threads to use.
    pub fn worker_threads(&self) -> usize {
        if self.threads > 0 {
            self.threads
        } else {
            std::thread::available_parallelism().map_or(1, |n| n.get())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::LocalBaConfig;

    #[test]
    fn an_iteration_share_keeps_the_first_stage_first() {
        let stages = |share: f64| {
            let c = LocalBaConfig::default().with_iteration_share(share);
            (c.first_stage_iterations, c.second_stage_iterations)
        };
        assert_eq!(stages(1.0), (5, 10));
        assert_eq!(stages(2.0), (5, 10));
        assert_eq!(stages(0.0), (0, 0));
        assert_eq!(stages(-1.0), (0, 0));
        assert_eq!(stages(1.0 / 3.0), (5, 0));
        assert_eq!(stages(0.2), (3, 0));
        assert_eq!(stages(2.0 / 3.0), (5, 5));
    }
}
