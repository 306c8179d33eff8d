//! The optimisation back end: Lie groups for poses, pose-only optimisation,
//! local bundle adjustment and pose graphs, written on nalgebra and faer
//! (the block-sparse Cholesky machinery shared by the pose graph and bundle
//! adjustment lives in the crate-internal `sparse` module).

pub mod damping;
pub mod error;
pub mod lie;
pub mod local_ba;
pub mod pose_graph;
pub mod pose_only;
pub mod reprojection;
pub(crate) mod sparse;

pub use error::OptimError;
pub use lie::{LieGroup, Se3, Sim3};
