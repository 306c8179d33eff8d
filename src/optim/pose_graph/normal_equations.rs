//! Assembly of the normal equations `H δ = −b` and the cost χ².
//!
//! For each edge with weight `w = ρ'(eᵀΩe)`: `H_ab += w J_aᵀ Ω J_b` and
//! `b_a += w J_aᵀ Ω e` for its free end nodes `a, b`, scattered into the
//! positions precomputed by [`BlockPattern`].

use nalgebra::{SMatrix, SVector};

use super::graph::PoseGraphEdge;
use super::kernel::robust_cost_and_weight;
use super::pattern::{BlockPattern, BlockSlot};
use super::residual::{edge_residual, linearise_edge_with_adjoint};
use crate::optim::lie::LieGroup;

/// `H` (upper-triangle CSC values), `b` and χ² at one linearisation point.
#[derive(Debug, Clone)]
pub(super) struct NormalEquations {
    /// Values of the upper triangle of `H` in the pattern's CSC order.
    pub hessian_values: Vec<f64>,
    /// The gradient `b = Σ w Jᵀ Ω e` (length `N · block_count`).
    pub gradient: Vec<f64>,
    /// `χ² = Σ ρ(eᵀ Ω e)`.
    pub chi2: f64,
}

impl NormalEquations {
    /// Zeroed buffers for a pattern.
    pub fn zeros<const N: usize>(pattern: &BlockPattern<N>) -> Self {
        Self {
            hessian_values: vec![0.0; pattern.value_count()],
            gradient: vec![0.0; pattern.dimension()],
            chi2: 0.0,
        }
    }

    /// Assembles `H`, `b` and χ² at `nodes`; `measurement_adjoints[k]` is
    /// `Ad_Z` of edge `k`.
    pub fn assemble<G: LieGroup<N>, const N: usize>(
        &mut self,
        pattern: &BlockPattern<N>,
        nodes: &[G],
        edges: &[PoseGraphEdge<G, N>],
        measurement_adjoints: &[SMatrix<f64, N, N>],
    ) {
        self.hessian_values.fill(0.0);
        self.gradient.fill(0.0);
        let mut chi2 = 0.0;
        for ((edge, slots), adjoint) in edges
            .iter()
            .zip(&pattern.edge_slots)
            .zip(measurement_adjoints)
        {
            let linear = linearise_edge_with_adjoint(
                &edge.measurement,
                adjoint,
                &nodes[edge.from],
                &nodes[edge.to],
            );
            let weighted_error = edge.information * linear.residual;
            let squared_error = linear.residual.dot(&weighted_error);
            let (cost, weight) = robust_cost_and_weight(edge.robust_kernel.as_ref(), squared_error);
            chi2 += cost;
            let weighted_information = edge.information * weight;
            // Jᵀ (wΩ) for each end.
            let from_t = linear.jacobian_from.transpose() * weighted_information;
            let to_t = linear.jacobian_to.transpose() * weighted_information;
            if let Some(block) = slots.from_block {
                add_diagonal_block(
                    &mut self.hessian_values,
                    &pattern.diagonal_slots[block],
                    &(from_t * linear.jacobian_from),
                );
                add_gradient(&mut self.gradient, block, &(from_t * linear.residual));
            }
            if let Some(block) = slots.to_block {
                add_diagonal_block(
                    &mut self.hessian_values,
                    &pattern.diagonal_slots[block],
                    &(to_t * linear.jacobian_to),
                );
                add_gradient(&mut self.gradient, block, &(to_t * linear.residual));
            }
            if let Some((slot, from_is_row)) = slots.off_diagonal {
                let block = if from_is_row {
                    from_t * linear.jacobian_to
                } else {
                    to_t * linear.jacobian_from
                };
                add_full_block(
                    &mut self.hessian_values,
                    &pattern.off_diagonal_slots[slot],
                    &block,
                );
            }
        }
        self.chi2 = chi2;
    }
}

/// `χ² = Σ ρ(eᵀ Ω e)` at `nodes`, without Jacobians.
pub(super) fn total_chi2<G: LieGroup<N>, const N: usize>(
    nodes: &[G],
    edges: &[PoseGraphEdge<G, N>],
) -> f64 {
    edges
        .iter()
        .map(|edge| {
            let residual = edge_residual(&edge.measurement, &nodes[edge.from], &nodes[edge.to]);
            let squared_error = residual.dot(&(edge.information * residual));
            robust_cost_and_weight(edge.robust_kernel.as_ref(), squared_error).0
        })
        .sum()
}

fn add_diagonal_block<const N: usize>(
    values: &mut [f64],
    slot: &BlockSlot<N>,
    block: &SMatrix<f64, N, N>,
) {
    // Lower triangle: column b holds rows b..N, starting at slot[b].
    for (b, &start) in slot.iter().enumerate() {
        let column = block.column(b);
        for (value, &entry) in values[start..start + N - b]
            .iter_mut()
            .zip(column.iter().skip(b))
        {
            *value += entry;
        }
    }
}

fn add_full_block<const N: usize>(
    values: &mut [f64],
    slot: &BlockSlot<N>,
    block: &SMatrix<f64, N, N>,
) {
    for (b, &start) in slot.iter().enumerate() {
        for (value, &entry) in values[start..start + N]
            .iter_mut()
            .zip(block.column(b).iter())
        {
            *value += entry;
        }
    }
}

fn add_gradient<const N: usize>(gradient: &mut [f64], block: usize, part: &SVector<f64, N>) {
    for (value, &entry) in gradient[block * N..block * N + N]
        .iter_mut()
        .zip(part.iter())
    {
        *value += entry;
    }
}
