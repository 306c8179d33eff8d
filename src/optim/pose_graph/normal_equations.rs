//! Assembly of the normal equations `H δ = −b` and the cost χ².
//!
//! For each edge with weight `w = ρ'(eᵀΩe)`: `H_ab += w J_aᵀ Ω J_b` and
//! `b_a += w J_aᵀ Ω e` for its free end nodes `a, b`, scattered into the
//! positions precomputed by [`BlockPattern`].

use nalgebra::{SMatrix, SVector};

use super::graph::PoseGraphEdge;
use super::kernel::robust_cost_and_weight;
use super::residual::{edge_residual, linearise_edge_with_adjoint};
use crate::optim::lie::LieGroup;
use crate::optim::sparse::{add_diagonal_block, add_full_block, BlockPattern};

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
    /// `Ad_Z` of edge `k`. The edges are split into `1 + partials.len()`
    /// contiguous ranges assembled on as many threads, `partials` being the
    /// extra threads' buffers, then summed (the result depends on the number
    /// of threads only through rounding).
    pub fn assemble<G: LieGroup<N> + Sync, const N: usize>(
        &mut self,
        partials: &mut [NormalEquations],
        pattern: &BlockPattern<N>,
        nodes: &[G],
        edges: &[PoseGraphEdge<G, N>],
        measurement_adjoints: &[SMatrix<f64, N, N>],
    ) {
        let chunk = edges.len().div_ceil(partials.len() + 1).max(1);
        let inputs = EdgeInputs {
            pattern,
            nodes,
            edges,
            measurement_adjoints,
        };
        std::thread::scope(|scope| {
            for (thread, partial) in partials.iter_mut().enumerate() {
                let start = ((thread + 1) * chunk).min(edges.len());
                let end = (start + chunk).min(edges.len());
                scope.spawn(move || partial.assemble_range(&inputs, start..end));
            }
            self.assemble_range(&inputs, 0..chunk.min(edges.len()));
        });
        for partial in partials.iter() {
            for (total, part) in self.hessian_values.iter_mut().zip(&partial.hessian_values) {
                *total += part;
            }
            for (total, part) in self.gradient.iter_mut().zip(&partial.gradient) {
                *total += part;
            }
            self.chi2 += partial.chi2;
        }
    }

    fn assemble_range<G: LieGroup<N>, const N: usize>(
        &mut self,
        inputs: &EdgeInputs<'_, G, N>,
        range: std::ops::Range<usize>,
    ) {
        self.hessian_values.fill(0.0);
        self.gradient.fill(0.0);
        let mut chi2 = 0.0;
        let pattern = inputs.pattern;
        let nodes = inputs.nodes;
        for ((edge, slots), adjoint) in inputs.edges[range.clone()]
            .iter()
            .zip(&pattern.edge_slots[range.clone()])
            .zip(&inputs.measurement_adjoints[range])
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

/// What every assembly thread reads.
struct EdgeInputs<'a, G, const N: usize> {
    pattern: &'a BlockPattern<N>,
    nodes: &'a [G],
    edges: &'a [PoseGraphEdge<G, N>],
    measurement_adjoints: &'a [SMatrix<f64, N, N>],
}

impl<G, const N: usize> Clone for EdgeInputs<'_, G, N> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<G, const N: usize> Copy for EdgeInputs<'_, G, N> {}

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

fn add_gradient<const N: usize>(gradient: &mut [f64], block: usize, part: &SVector<f64, N>) {
    for (value, &entry) in gradient[block * N..block * N + N]
        .iter_mut()
        .zip(part.iter())
    {
        *value += entry;
    }
}
