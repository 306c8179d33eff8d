//! Block-sparse symmetric positive-definite systems, shared by the pose
//! graph ([`crate::optim::pose_graph`]) and bundle adjustment's sparse
//! reduced camera system ([`crate::optim::local_ba`]).
//!
//! The sparse path, for `N×N` blocks (`N` = 6 for SE3 poses, 7 for Sim3):
//! 1. [`BlockPattern::new`] takes the free nodes and the node pairs coupled
//!    in the system (pose-graph edges; in bundle adjustment, the free pose
//!    pairs that share a point) and orders the block columns by AMD on the
//!    block graph ([`ordering`]), so fill-in stays low and faer never
//!    permutes the matrix;
//! 2. the pattern lays out the lower triangle in compressed sparse columns
//!    and records, for every diagonal and off-diagonal block, where each of
//!    its `N` columns starts in the value array ([`BlockSlot`]), so assembly
//!    is a scatter ([`add_diagonal_block`], [`add_full_block`]) with no
//!    search;
//! 3. [`SparseCholesky::analyse`] runs faer's symbolic (supernodal)
//!    Cholesky analysis once per pattern; each solve then only refactorises
//!    numerically ([`SparseCholesky::factorise_and_solve`]).
//!
//! Vectors (right-hand sides, solutions) are in the elimination order:
//! block `BlockPattern::block_of_node[node]` holds a node's `N` entries.

mod cholesky;
mod ordering;
mod pattern;

pub(crate) use cholesky::SparseCholesky;
pub(crate) use pattern::{add_diagonal_block, add_full_block, BlockPattern, BlockSlot};
