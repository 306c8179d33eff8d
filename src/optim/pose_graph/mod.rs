//! Pose-graph optimisation over SE(3) or Sim(3), as ORB-SLAM3 runs after a
//! loop closure (`Optimizer::OptimizeEssentialGraph`: Sim3 for monocular,
//! SE3 / 6-DoF when the scale is observed).
//!
//! One generic implementation over [`LieGroup`](crate::optim::lie::LieGroup):
//! - [`PoseGraph`]: world→camera node poses `T_i`, fixed flags, edges
//!   `i → j` with measurement `Z_ij ≈ T_j T_i⁻¹`, information `Ω` and an
//!   optional [`RobustKernel`];
//! - residual `e = log(Z_ij · T_i · T_j⁻¹)` with analytic Jacobians
//!   ([`residual`]);
//! - [`PoseGraphSolver`]: Gauss–Newton or Levenberg–Marquardt on the sparse
//!   normal equations, assembled straight into a block-CSC pattern and solved
//!   by faer's sparse Cholesky whose symbolic factorisation is computed once
//!   (the pattern, ordering and Cholesky live in the crate-internal
//!   `optim::sparse` module, shared with bundle adjustment's sparse reduced
//!   camera system).

mod graph;
mod kernel;
mod normal_equations;
pub mod residual;
mod solver;
mod summary;

pub use graph::{PoseGraph, PoseGraphEdge};
pub use kernel::RobustKernel;
pub use solver::PoseGraphSolver;
pub use summary::{Algorithm, IterationRecord, PoseGraphOptions, PoseGraphSummary, Termination};

use crate::optim::lie::{Se3, Sim3};

/// A 6-DoF pose graph (scale fixed, e.g. stereo / RGB-D).
pub type Se3PoseGraph = PoseGraph<Se3, 6>;
/// A 7-DoF pose graph (monocular: scale drift corrected).
pub type Sim3PoseGraph = PoseGraph<Sim3, 7>;
/// An SE3 edge.
pub type Se3PoseGraphEdge = PoseGraphEdge<Se3, 6>;
/// A Sim3 edge.
pub type Sim3PoseGraphEdge = PoseGraphEdge<Sim3, 7>;
