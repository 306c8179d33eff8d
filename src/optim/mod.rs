//! The optimisation back end: Lie groups for poses, pose-only optimisation,
//! local bundle adjustment and pose graphs, written on nalgebra and faer.

pub mod lie;

pub use lie::{LieGroup, Se3, Sim3};
