//! What local bundle adjustment reports.

/// Why a stage of Levenberg–Marquardt stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Termination {
    /// The relative cost decrease fell below the tolerance.
    CostConverged,
    /// The step fell below the tolerance.
    StepConverged,
    /// The cost reached zero.
    ZeroCost,
    /// No damping tried in one iteration lowered the cost (a minimum, to precision).
    NoDecrease,
    /// The iteration limit was reached.
    IterationLimit,
    /// The stage had nothing to optimise (no iterations requested).
    Skipped,
    /// The abort flag was raised (ORB-SLAM3's `mbAbortBA`): the stage
    /// stopped after its current iteration, keeping its best state.
    Aborted,
}

/// One Levenberg–Marquardt stage.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StageReport {
    /// Iterations run (linearisations).
    pub iterations: usize,
    /// Linear solves, accepted or not.
    pub solves: usize,
    /// The stage's cost (Huber or plain χ² sum over active observations) at its start.
    pub initial_cost: f64,
    /// The same cost at its end.
    pub final_cost: f64,
    /// Why it stopped.
    pub termination: Termination,
}

/// The outcome of [`super::local_bundle_adjustment`].
#[derive(Debug, Clone, PartialEq)]
pub struct LocalBaReport {
    /// The first (robust) stage.
    pub first_stage: StageReport,
    /// The second stage, over the first stage's inliers.
    pub second_stage: StageReport,
    /// Indices into the problem's observations that are outliers at the end
    /// (χ² above 5.991 / 7.815, or the point behind the camera), ascending;
    /// the map should erase them.
    pub outliers: Vec<usize>,
    /// Sum of the inliers' χ² at the end (no kernel).
    pub inlier_chi2_sum: f64,
    /// The pose fixed to remove the gauge freedom when none was fixed.
    pub gauge_fixed_pose: Option<usize>,
}
