//! The pose graph: flat node and edge vectors, validated on insertion.

use nalgebra::{Cholesky, SMatrix};

use super::kernel::RobustKernel;
use crate::optim::error::OptimError;
use crate::optim::lie::LieGroup;

/// One relative-pose constraint between nodes `from = i` and `to = j`.
///
/// The measurement is `Z_ij ≈ T_j · T_i⁻¹` for world→camera node poses
/// (ORB-SLAM3's `S_ji`); the residual is `e = log(Z_ij · T_i · T_j⁻¹)` and
/// its cost `ρ(eᵀ Ω e)` (see [`super::residual`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseGraphEdge<G, const N: usize> {
    /// Index of node `i`.
    pub from: usize,
    /// Index of node `j`.
    pub to: usize,
    /// The measured relative transform `Z_ij`.
    pub measurement: G,
    /// The information matrix `Ω` (symmetric positive definite), in the
    /// tangent order of `G` (rotation first).
    pub information: SMatrix<f64, N, N>,
    /// An optional robust kernel on `eᵀ Ω e`.
    pub robust_kernel: Option<RobustKernel>,
}

impl<G: LieGroup<N>, const N: usize> PoseGraphEdge<G, N> {
    /// An edge with identity information and no robust kernel (ORB-SLAM3's
    /// essential-graph edges).
    pub fn new(from: usize, to: usize, measurement: G) -> Self {
        Self {
            from,
            to,
            measurement,
            information: SMatrix::identity(),
            robust_kernel: None,
        }
    }

    /// The same edge with information matrix `information`.
    pub fn with_information(mut self, information: SMatrix<f64, N, N>) -> Self {
        self.information = information;
        self
    }

    /// The same edge with a robust kernel.
    pub fn with_robust_kernel(mut self, kernel: RobustKernel) -> Self {
        self.robust_kernel = Some(kernel);
        self
    }
}

/// A pose graph over the Lie group `G` with `N` degrees of freedom.
///
/// Nodes are world→camera poses; nodes flagged fixed are never changed by
/// the optimiser (they stay bit-identical). Edges are checked when added, so
/// an existing graph is always valid input for the solver.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseGraph<G, const N: usize> {
    nodes: Vec<G>,
    fixed: Vec<bool>,
    edges: Vec<PoseGraphEdge<G, N>>,
}

impl<G, const N: usize> Default for PoseGraph<G, N> {
    fn default() -> Self {
        Self {
            nodes: Vec::new(),
            fixed: Vec::new(),
            edges: Vec::new(),
        }
    }
}

impl<G: LieGroup<N>, const N: usize> PoseGraph<G, N> {
    /// An empty graph.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a node and returns its index. Refuses non-finite poses (and
    /// Sim3 poses of non-positive scale).
    pub fn add_node(&mut self, pose: G, fixed: bool) -> Result<usize, OptimError> {
        let node = self.nodes.len();
        if !is_valid_element(&pose) {
            return Err(OptimError::InvalidNode { node });
        }
        self.nodes.push(pose);
        self.fixed.push(fixed);
        Ok(node)
    }

    /// Adds an edge after checking it and returns its index.
    pub fn add_edge(&mut self, edge: PoseGraphEdge<G, N>) -> Result<usize, OptimError> {
        let index = self.edges.len();
        self.check_edge(index, &edge)?;
        self.edges.push(edge);
        Ok(index)
    }

    /// Marks a node fixed (held constant) or free.
    pub fn set_fixed(&mut self, node: usize, fixed: bool) -> Result<(), OptimError> {
        let nodes = self.nodes.len();
        let flag = self
            .fixed
            .get_mut(node)
            .ok_or(OptimError::UnknownNode { node, nodes })?;
        *flag = fixed;
        Ok(())
    }

    /// Replaces a node's pose (e.g. to re-initialise it).
    pub fn set_node(&mut self, node: usize, pose: G) -> Result<(), OptimError> {
        if !is_valid_element(&pose) {
            return Err(OptimError::InvalidNode { node });
        }
        let nodes = self.nodes.len();
        let slot = self
            .nodes
            .get_mut(node)
            .ok_or(OptimError::UnknownNode { node, nodes })?;
        *slot = pose;
        Ok(())
    }

    /// All node poses, by index.
    pub fn nodes(&self) -> &[G] {
        &self.nodes
    }

    /// The fixed flag of every node, by index.
    pub fn fixed_flags(&self) -> &[bool] {
        &self.fixed
    }

    /// All edges, by index.
    pub fn edges(&self) -> &[PoseGraphEdge<G, N>] {
        &self.edges
    }

    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Mutable node poses, for the solver (same length as `fixed_flags`).
    pub(super) fn nodes_mut(&mut self) -> &mut [G] {
        &mut self.nodes
    }

    fn check_edge(&self, edge: usize, candidate: &PoseGraphEdge<G, N>) -> Result<(), OptimError> {
        let nodes = self.nodes.len();
        for node in [candidate.from, candidate.to] {
            if node >= nodes {
                return Err(OptimError::NodeOutOfRange { edge, node, nodes });
            }
        }
        if candidate.from == candidate.to {
            return Err(OptimError::SelfLoopEdge {
                edge,
                node: candidate.from,
            });
        }
        if !is_valid_element(&candidate.measurement) {
            return Err(OptimError::InvalidMeasurement { edge });
        }
        if !is_symmetric_positive_definite(&candidate.information) {
            return Err(OptimError::InformationNotPositiveDefinite { edge });
        }
        if let Some(kernel) = candidate.robust_kernel {
            let width = kernel.width();
            if !(width.is_finite() && width > 0.0) {
                return Err(OptimError::InvalidKernelWidth { edge, width });
            }
        }
        Ok(())
    }
}

/// Finite entries and a positive determinant of the linear part (rules out
/// NaN, infinities and Sim3 scales ≤ 0).
fn is_valid_element<G: LieGroup<N>, const N: usize>(element: &G) -> bool {
    let matrix = element.to_matrix();
    let linear_determinant = matrix.fixed_view::<3, 3>(0, 0).determinant();
    matrix.iter().all(|value| value.is_finite()) && linear_determinant > 0.0
}

/// Finite, symmetric to a relative 1e-9, and Cholesky-factorisable.
fn is_symmetric_positive_definite<const N: usize>(matrix: &SMatrix<f64, N, N>) -> bool {
    if !matrix.iter().all(|value| value.is_finite()) {
        return false;
    }
    let asymmetry = (matrix - matrix.transpose()).amax();
    if asymmetry > 1e-9 * matrix.amax() {
        return false;
    }
    Cholesky::new(*matrix).is_some()
}
