//! The optimisation back end: Lie groups for poses, pose-only optimisation,
//! local bundle adjustment and pose graphs, written on nalgebra and faer.

pub mod damping;
pub mod error;
pub mod lie;
pub mod local_ba;
pub mod pose_graph;
pub mod pose_only;
pub mod reprojection;

pub use error::OptimError;
pub use lie::{LieGroup, Se3, Sim3};
