//! Gauss–Newton / Levenberg–Marquardt on the sparse normal equations.
//!
//! [`PoseGraphSolver::new`] builds the block pattern and runs the symbolic
//! Cholesky analysis once; every iteration then assembles `H` and `b` into
//! the fixed pattern, adds the damping to the diagonal, refactorises
//! numerically and solves.

use std::time::Instant;

use nalgebra::{SMatrix, SVector};

use super::graph::PoseGraph;
use super::normal_equations::{total_chi2, NormalEquations};
use super::summary::{Algorithm, IterationRecord, PoseGraphOptions, PoseGraphSummary, Termination};
use crate::optim::error::OptimError;
use crate::optim::lie::LieGroup;
use crate::optim::sparse::{BlockPattern, SparseCholesky};

/// Fewest edges per assembly thread (smaller graphs are assembled on fewer).
const EDGES_PER_ASSEMBLY_THREAD: usize = 1000;

/// Damping beyond which LM gives up (the step is then negligible anyway).
const MAX_LAMBDA: f64 = 1e32;

/// A solver bound to one graph, holding the pattern and symbolic factorisation.
///
/// Gauge: nodes flagged fixed are held constant. If no node is flagged
/// fixed, the lowest-index node that has an edge (node 0 in any graph where
/// node 0 has an edge) is held constant instead, and reported as
/// [`PoseGraphSummary::auto_fixed_node`]; the graph's flags are not changed.
/// Nodes without edges are left untouched. A connected component with no
/// constant node has a free gauge: LM's damping copes, Gauss–Newton fails
/// with [`OptimError::NotPositiveDefinite`].
#[derive(Debug)]
pub struct PoseGraphSolver<'g, G, const N: usize> {
    graph: &'g mut PoseGraph<G, N>,
    options: PoseGraphOptions,
    auto_fixed_node: Option<usize>,
    pattern: BlockPattern<N>,
    measurement_adjoints: Vec<SMatrix<f64, N, N>>,
    cholesky: Option<SparseCholesky>,
    current: NormalEquations,
    candidate: NormalEquations,
    partials: Vec<NormalEquations>,
    damped_values: Vec<f64>,
    step: Vec<f64>,
    candidate_nodes: Vec<G>,
    symbolic_seconds: f64,
    iteration: usize,
}

impl<'g, G: LieGroup<N> + Send + Sync, const N: usize> PoseGraphSolver<'g, G, N> {
    /// Validates the options, builds the pattern and runs the symbolic factorisation.
    pub fn new(
        graph: &'g mut PoseGraph<G, N>,
        options: PoseGraphOptions,
    ) -> Result<Self, OptimError> {
        options.validate()?;
        let start = Instant::now();
        let node_count = graph.node_count();
        let mut has_edge = vec![false; node_count];
        let edge_ends: Vec<(usize, usize)> = graph
            .edges()
            .iter()
            .map(|edge| {
                has_edge[edge.from] = true;
                has_edge[edge.to] = true;
                (edge.from, edge.to)
            })
            .collect();
        let fixed = graph.fixed_flags();
        let auto_fixed_node = if fixed.iter().any(|&flag| flag) {
            None
        } else {
            has_edge.iter().position(|&flag| flag)
        };
        let held_constant: Vec<bool> = (0..node_count)
            .map(|node| fixed[node] || !has_edge[node] || auto_fixed_node == Some(node))
            .collect();
        let pattern = BlockPattern::<N>::new(&held_constant, &edge_ends)?;
        let cholesky = if pattern.dimension() == 0 {
            None
        } else {
            Some(SparseCholesky::analyse(
                pattern.dimension(),
                &pattern.column_pointers,
                &pattern.row_indices,
            )?)
        };
        let symbolic_seconds = start.elapsed().as_secs_f64();
        let assembly_threads = options
            .assembly_threads
            .min(graph.edges().len() / EDGES_PER_ASSEMBLY_THREAD)
            .max(1);
        let measurement_adjoints = graph
            .edges()
            .iter()
            .map(|edge| edge.measurement.adjoint())
            .collect();
        Ok(Self {
            measurement_adjoints,
            current: NormalEquations::zeros(&pattern),
            candidate: NormalEquations::zeros(&pattern),
            partials: (1..assembly_threads)
                .map(|_| NormalEquations::zeros(&pattern))
                .collect(),
            damped_values: vec![0.0; pattern.value_count()],
            step: vec![0.0; pattern.dimension()],
            candidate_nodes: graph.nodes().to_vec(),
            graph,
            options,
            auto_fixed_node,
            pattern,
            cholesky,
            symbolic_seconds,
            iteration: 0,
        })
    }

    /// The graph being optimised.
    pub fn graph(&self) -> &PoseGraph<G, N> {
        self.graph
    }

    /// The node held constant for the gauge, if none was flagged fixed.
    pub fn auto_fixed_node(&self) -> Option<usize> {
        self.auto_fixed_node
    }

    /// Size of the linear system (`N` per free node).
    pub fn dimension(&self) -> usize {
        self.pattern.dimension()
    }

    /// Seconds spent on the pattern and symbolic factorisation.
    pub fn symbolic_seconds(&self) -> f64 {
        self.symbolic_seconds
    }

    /// Assembles `H` and `b` at the graph's current poses and returns χ².
    pub fn linearise(&mut self) -> f64 {
        self.current.assemble(
            &mut self.partials,
            &self.pattern,
            self.graph.nodes(),
            self.graph.edges(),
            &self.measurement_adjoints,
        );
        self.current.chi2
    }

    /// The block (position in the solver's variable order, `N` entries
    /// each) of a node, `None` for nodes held constant.
    pub fn block_of_node(&self, node: usize) -> Option<usize> {
        self.pattern.block_of_node.get(node).copied().flatten()
    }

    /// The last linearisation as a dense `H` (both triangles) and `b`, in the
    /// solver's variable order (see [`Self::block_of_node`]). For checks on
    /// small problems.
    pub fn dense_normal_equations(&self) -> (Vec<Vec<f64>>, Vec<f64>) {
        let dimension = self.dimension();
        let mut hessian = vec![vec![0.0; dimension]; dimension];
        let pointers = &self.pattern.column_pointers;
        for (column, bounds) in pointers.windows(2).enumerate() {
            for position in bounds[0]..bounds[1] {
                let row = self.pattern.row_indices[position];
                let value = self.current.hessian_values[position];
                hessian[row][column] = value;
                hessian[column][row] = value;
            }
        }
        (hessian, self.current.gradient.clone())
    }

    /// Solves `(H + λI) δ = −b` for the last linearisation and returns `δ`
    /// in the solver's variable order (see [`Self::block_of_node`]; left
    /// perturbations).
    pub fn solve_step(&mut self, lambda: f64) -> Result<&[f64], OptimError> {
        self.solve_damped(lambda)
            .map_err(|pivot| OptimError::NotPositiveDefinite {
                iteration: self.iteration,
                pivot,
            })?;
        Ok(&self.step)
    }

    fn solve_damped(&mut self, lambda: f64) -> Result<(), usize> {
        let Some(cholesky) = self.cholesky.as_mut() else {
            return Ok(());
        };
        self.damped_values
            .copy_from_slice(&self.current.hessian_values);
        for &index in &self.pattern.diagonal_value_indices {
            self.damped_values[index] += lambda;
        }
        for (step, gradient) in self.step.iter_mut().zip(&self.current.gradient) {
            *step = -gradient;
        }
        cholesky.factorise_and_solve(&self.damped_values, &mut self.step)
    }

    /// Writes `exp(δ_k) · T_k` for every free node into `candidate_nodes`.
    fn apply_step(&mut self) {
        for (node, block) in self.pattern.block_of_node.iter().enumerate() {
            if let Some(block) = *block {
                let delta =
                    SVector::<f64, N>::from_column_slice(&self.step[block * N..block * N + N]);
                self.candidate_nodes[node] = self.graph.nodes()[node].perturb_left(&delta);
            }
        }
    }

    /// Runs the optimisation to a termination criterion; the graph's free
    /// nodes hold the result (fixed nodes are never written).
    pub fn optimise(&mut self) -> Result<PoseGraphSummary, OptimError> {
        let start = Instant::now();
        let linearisation_start = Instant::now();
        let initial_chi2 = if self.cholesky.is_some() {
            self.linearise()
        } else {
            total_chi2(self.graph.nodes(), self.graph.edges())
        };
        let initial_linearisation_seconds = linearisation_start.elapsed().as_secs_f64();
        let mut summary = PoseGraphSummary {
            iterations: 0,
            initial_chi2,
            final_chi2: initial_chi2,
            termination: Termination::NothingToOptimise,
            auto_fixed_node: self.auto_fixed_node,
            free_nodes: self.pattern.block_count,
            symbolic_seconds: self.symbolic_seconds,
            initial_linearisation_seconds,
            total_seconds: 0.0,
            iteration_log: Vec::new(),
        };
        if self.cholesky.is_some() {
            summary.termination = self.iterate(&mut summary.iteration_log)?;
        }
        summary.iterations = summary.iteration_log.len();
        summary.final_chi2 = if self.cholesky.is_some() {
            self.current.chi2
        } else {
            initial_chi2
        };
        summary.total_seconds = start.elapsed().as_secs_f64() + self.symbolic_seconds;
        Ok(summary)
    }

    fn iterate(&mut self, log: &mut Vec<IterationRecord>) -> Result<Termination, OptimError> {
        let levenberg = self.options.algorithm == Algorithm::LevenbergMarquardt;
        let mut lambda = if levenberg {
            let max_diagonal = self
                .pattern
                .diagonal_value_indices
                .iter()
                .map(|&index| self.current.hessian_values[index])
                .fold(0.0, f64::max);
            self.options.initial_lambda_scale * max_diagonal
        } else {
            0.0
        };
        let mut lambda_growth = 2.0;
        for iteration in 0..self.options.max_iterations {
            self.iteration = iteration;
            if self.current.chi2 <= self.options.absolute_chi2_tolerance {
                return Ok(Termination::AbsoluteChi2);
            }
            let started = Instant::now();
            if let Err(pivot) = self.solve_damped(lambda) {
                if !levenberg {
                    return Err(OptimError::NotPositiveDefinite { iteration, pivot });
                }
                log.push(IterationRecord {
                    candidate_chi2: f64::NAN,
                    lambda,
                    accepted: false,
                    seconds: started.elapsed().as_secs_f64(),
                });
                lambda = (lambda * lambda_growth).max(1e-12);
                lambda_growth *= 2.0;
                if lambda > MAX_LAMBDA {
                    return Ok(Termination::NoDecrease);
                }
                continue;
            }
            let largest_step = self
                .step
                .iter()
                .fold(0.0f64, |max, value| max.max(value.abs()));
            if largest_step <= self.options.step_tolerance {
                return Ok(Termination::SmallStep);
            }
            self.apply_step();
            self.candidate.assemble(
                &mut self.partials,
                &self.pattern,
                &self.candidate_nodes,
                self.graph.edges(),
                &self.measurement_adjoints,
            );
            let current_chi2 = self.current.chi2;
            let candidate_chi2 = self.candidate.chi2;
            let accepted = candidate_chi2.is_finite() && candidate_chi2 < current_chi2;
            let record_lambda = lambda;
            if accepted {
                // Predicted decrease of the linear model: δᵀ(λδ − b).
                let predicted: f64 = self
                    .step
                    .iter()
                    .zip(&self.current.gradient)
                    .map(|(step, gradient)| step * (lambda * step - gradient))
                    .sum();
                self.accept_candidate();
                if levenberg {
                    let gain = (current_chi2 - candidate_chi2) / predicted.max(f64::MIN_POSITIVE);
                    lambda *= (1.0 - (2.0 * gain - 1.0).powi(3)).max(1.0 / 3.0);
                    lambda_growth = 2.0;
                }
            } else if levenberg {
                lambda *= lambda_growth;
                lambda_growth *= 2.0;
            }
            log.push(IterationRecord {
                candidate_chi2,
                lambda: record_lambda,
                accepted,
                seconds: started.elapsed().as_secs_f64(),
            });
            if accepted {
                let decrease = (current_chi2 - candidate_chi2) / current_chi2;
                if decrease < self.options.relative_chi2_tolerance {
                    return Ok(Termination::RelativeDecrease);
                }
            } else if !levenberg || lambda > MAX_LAMBDA {
                return Ok(Termination::NoDecrease);
            }
        }
        Ok(
            if self.current.chi2 <= self.options.absolute_chi2_tolerance {
                Termination::AbsoluteChi2
            } else {
                Termination::MaxIterations
            },
        )
    }

    /// Copies the free candidate poses into the graph and swaps the
    /// linearisations; fixed nodes are never written.
    fn accept_candidate(&mut self) {
        let nodes = self.graph.nodes_mut();
        for (node, block) in self.pattern.block_of_node.iter().enumerate() {
            if block.is_some() {
                nodes[node] = self.candidate_nodes[node];
            }
        }
        std::mem::swap(&mut self.current, &mut self.candidate);
    }
}

impl<G: LieGroup<N> + Send + Sync, const N: usize> PoseGraph<G, N> {
    /// Optimises the graph in place (see [`PoseGraphSolver`]).
    pub fn optimise(&mut self, options: &PoseGraphOptions) -> Result<PoseGraphSummary, OptimError> {
        PoseGraphSolver::new(self, *options)?.optimise()
    }
}
