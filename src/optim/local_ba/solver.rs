//! One Levenberg–Marquardt stage over the Schur-reduced camera system.

use std::sync::atomic::{AtomicBool, Ordering};

use nalgebra::{Cholesky, DMatrix, DVector, Matrix6, Vector3, Vector6};

use super::chunk::{pose_matrices, PassInputs, PointChunk, ReducedPart};
use super::config::LocalBaConfig;
use super::layout::Layout;
use super::parallel::for_each_chunk;
use super::report::{StageReport, Termination};
use super::sparse_schur::{ReducedPattern, SparseReducedSolver};
use crate::optim::damping::{gain_ratio, marquardt_scale, predicted_decrease, NielsenDamping};
use crate::optim::reprojection::{PinholeStereo, PoseMatrix};
use crate::optim::{LieGroup, OptimError, Se3};

/// The state being optimised: poses and points, updated in place.
pub(super) struct State<'a> {
    /// Keyframe poses `T_cw`.
    pub poses: &'a mut [Se3],
    /// World points.
    pub points: &'a mut [Vector3<f64>],
}

/// Which observations a stage optimises, and how.
pub(super) struct StageSettings<'a> {
    /// Per sorted observation: take part.
    pub active: &'a [bool],
    /// Huber kernel on.
    pub robust: bool,
    /// Iteration limit.
    pub iterations: usize,
    /// Stop after the current iteration once this is raised.
    pub abort: Option<&'a AtomicBool>,
}

/// The solver's working memory, allocated once per bundle adjustment.
pub(super) struct Solver<'a> {
    camera: &'a PinholeStereo,
    layout: &'a Layout,
    config: &'a LocalBaConfig,
    reduced_pattern: Option<&'a ReducedPattern>,
    sparse: Option<SparseReducedSolver>,
    chunks: Vec<PointChunk>,
    poses: Vec<PoseMatrix>,
    candidate_poses: Vec<Se3>,
    candidate_matrices: Vec<PoseMatrix>,
    pose_hessian: Vec<Matrix6<f64>>,
    pose_gradient: Vec<Vector6<f64>>,
    pose_steps: Vec<Vector6<f64>>,
}

/// Sums over the chunks and the free poses after a step pass.
struct StepOutcome {
    cost: f64,
    step_norm_squared: f64,
    step_scaled_norm_squared: f64,
    step_dot_gradient: f64,
    state_norm_squared: f64,
}

impl<'a> Solver<'a> {
    /// Allocates the working memory for `layout`; with `reduced_pattern`
    /// the reduced camera system takes the sparse path (its symbolic
    /// analysis runs here, once).
    pub fn new(
        camera: &'a PinholeStereo,
        layout: &'a Layout,
        reduced_pattern: Option<&'a ReducedPattern>,
        config: &'a LocalBaConfig,
    ) -> Result<Self, OptimError> {
        let chunks = layout
            .chunks
            .iter()
            .map(|range| PointChunk::new(layout, range.clone(), reduced_pattern))
            .collect();
        let free = layout.free_poses.len();
        let sparse = match reduced_pattern {
            Some(pattern) if free > 0 => Some(SparseReducedSolver::new(pattern)?),
            _ => None,
        };
        Ok(Self {
            camera,
            layout,
            config,
            reduced_pattern,
            sparse,
            chunks,
            poses: Vec::new(),
            candidate_poses: Vec::new(),
            candidate_matrices: Vec::new(),
            pose_hessian: vec![Matrix6::zeros(); free],
            pose_gradient: vec![Vector6::zeros(); free],
            pose_steps: vec![Vector6::zeros(); free],
        })
    }

    fn inputs<'s>(&self, state: &'s State<'_>, stage: &'s StageSettings<'_>) -> PassInputs<'s>
    where
        'a: 's,
    {
        PassInputs {
            camera: self.camera,
            layout: self.layout,
            active: stage.active,
            robust: stage.robust,
            points: state.points,
            reduced_pattern: self.reduced_pattern,
        }
    }

    /// Linearises at the current state; returns the cost.
    fn linearise(&mut self, state: &State<'_>, stage: &StageSettings<'_>) -> f64 {
        pose_matrices(state.poses, &mut self.poses);
        let inputs = self.inputs(state, stage);
        let poses = &self.poses;
        for_each_chunk(&mut self.chunks, |chunk| chunk.linearise(&inputs, poses));
        self.pose_hessian.fill(Matrix6::zeros());
        self.pose_gradient.fill(Vector6::zeros());
        let mut cost = 0.0;
        for chunk in &self.chunks {
            cost += chunk.sums.cost;
            for (total, part) in self.pose_hessian.iter_mut().zip(&chunk.pose_hessian) {
                *total += part;
            }
            for (total, part) in self.pose_gradient.iter_mut().zip(&chunk.pose_gradient) {
                *total += part;
            }
        }
        cost
    }

    /// Solves the damped reduced system for the pose steps; false when singular.
    fn solve_poses(&mut self, state: &State<'_>, stage: &StageSettings<'_>, mu: f64) -> bool {
        let inputs = self.inputs(state, stage);
        for_each_chunk(&mut self.chunks, |chunk| chunk.reduce(&inputs, mu));
        let singular = self.chunks.iter().any(|c| c.sums.singular);
        if singular {
            return false;
        }
        let free = self.layout.free_poses.len();
        if free == 0 {
            return true;
        }
        let n = 6 * free;
        let mut rhs = DVector::<f64>::zeros(n);
        for chunk in &self.chunks {
            rhs += &chunk.reduced_rhs;
        }
        for f in 0..free {
            let mut r = rhs.fixed_rows_mut::<6>(6 * f);
            r -= self.pose_gradient[f];
        }
        if let (Some(sparse), Some(pattern)) = (self.sparse.as_mut(), self.reduced_pattern) {
            let parts = self.chunks.iter().filter_map(|chunk| match &chunk.reduced {
                ReducedPart::Sparse(values) => Some(values.as_slice()),
                ReducedPart::Dense(_) => None,
            });
            return sparse.solve(
                pattern,
                parts,
                &self.pose_hessian,
                mu,
                &rhs,
                &mut self.pose_steps,
            );
        }
        let mut reduced = DMatrix::<f64>::zeros(n, n);
        for chunk in &self.chunks {
            if let ReducedPart::Dense(part) = &chunk.reduced {
                reduced += part;
            }
        }
        for f in 0..free {
            let mut block = reduced.fixed_view_mut::<6, 6>(6 * f, 6 * f);
            let h = &self.pose_hessian[f];
            block += h + Matrix6::from_diagonal(&(h.diagonal().map(marquardt_scale) * mu));
        }
        for c in 0..n {
            for r in (c + 1)..n {
                reduced[(r, c)] = reduced[(c, r)];
            }
        }
        let Some(cholesky) = Cholesky::new(reduced) else {
            return false;
        };
        let steps = cholesky.solve(&rhs);
        if !steps.iter().all(|v| v.is_finite()) {
            return false;
        }
        for (f, step) in self.pose_steps.iter_mut().enumerate() {
            *step = steps.fixed_rows::<6>(6 * f).into_owned();
        }
        true
    }

    /// Applies the pose steps to candidates, back-substitutes the points
    /// and evaluates the candidate cost.
    fn step_and_evaluate(&mut self, state: &State<'_>, stage: &StageSettings<'_>) -> StepOutcome {
        self.candidate_poses.clear();
        self.candidate_poses.extend_from_slice(state.poses);
        let mut outcome = StepOutcome {
            cost: 0.0,
            step_norm_squared: 0.0,
            step_scaled_norm_squared: 0.0,
            step_dot_gradient: 0.0,
            state_norm_squared: 0.0,
        };
        for (f, &pose) in self.layout.free_poses.iter().enumerate() {
            let step = &self.pose_steps[f];
            self.candidate_poses[pose] = state.poses[pose].perturb_left(step);
            outcome.step_norm_squared += step.norm_squared();
            let scale = self.pose_hessian[f].diagonal().map(marquardt_scale);
            outcome.step_scaled_norm_squared += step.component_mul(&scale).dot(step);
            outcome.step_dot_gradient += step.dot(&self.pose_gradient[f]);
            outcome.state_norm_squared += state.poses[pose].translation.norm_squared();
        }
        pose_matrices(&self.candidate_poses, &mut self.candidate_matrices);
        let inputs = self.inputs(state, stage);
        let (steps, matrices) = (&self.pose_steps, &self.candidate_matrices);
        for_each_chunk(&mut self.chunks, |chunk| {
            chunk.step_and_evaluate(&inputs, steps, matrices)
        });
        for chunk in &self.chunks {
            outcome.cost += chunk.sums.cost;
            outcome.step_norm_squared += chunk.sums.step_norm_squared;
            outcome.step_scaled_norm_squared += chunk.sums.step_scaled_norm_squared;
            outcome.step_dot_gradient += chunk.sums.step_dot_gradient;
            outcome.state_norm_squared += chunk.sums.state_norm_squared;
        }
        outcome
    }

    /// Moves the candidate state into `state` (fixed poses are never written).
    fn accept(&self, state: &mut State<'_>) {
        for &pose in &self.layout.free_poses {
            state.poses[pose] = self.candidate_poses[pose];
        }
        for chunk in &self.chunks {
            state.points[chunk.points.clone()].copy_from_slice(&chunk.candidate_points);
        }
    }

    /// Runs one LM stage. Errors only when the starting cost is not finite.
    pub fn run_stage(
        &mut self,
        state: &mut State<'_>,
        stage: &StageSettings<'_>,
    ) -> Result<StageReport, OptimError> {
        let mut cost = self.linearise(state, stage);
        if !cost.is_finite() {
            return Err(OptimError::NonFiniteInitialCost);
        }
        let mut report = StageReport {
            iterations: 0,
            solves: 0,
            initial_cost: cost,
            final_cost: cost,
            termination: Termination::IterationLimit,
        };
        if stage.iterations == 0 {
            report.termination = Termination::Skipped;
            return Ok(report);
        }
        if stage.abort.is_some_and(|a| a.load(Ordering::Acquire)) {
            report.termination = Termination::Aborted;
            return Ok(report);
        }
        let mut damping = NielsenDamping::new(self.config.initial_damping);
        for iteration in 0..stage.iterations {
            if cost == 0.0 {
                report.termination = Termination::ZeroCost;
                break;
            }
            if iteration > 0 {
                cost = self.linearise(state, stage);
            }
            report.iterations += 1;
            let mut accepted = None;
            for _ in 0..self.config.max_tries_per_iteration.max(1) {
                report.solves += 1;
                let mu = damping.mu();
                if !self.solve_poses(state, stage, mu) {
                    damping.reject();
                    continue;
                }
                let outcome = self.step_and_evaluate(state, stage);
                let predicted = predicted_decrease(
                    mu,
                    outcome.step_scaled_norm_squared,
                    outcome.step_dot_gradient,
                );
                let rho = gain_ratio(cost, outcome.cost, predicted);
                if rho > 0.0 {
                    damping.accept(rho);
                    accepted = Some(outcome);
                    break;
                }
                damping.reject();
            }
            let Some(outcome) = accepted else {
                report.termination = Termination::NoDecrease;
                break;
            };
            self.accept(state);
            let decrease = cost - outcome.cost;
            cost = outcome.cost;
            report.final_cost = cost;
            let tol = self.config.relative_step_tolerance;
            let step_small =
                outcome.step_norm_squared.sqrt() <= tol * (outcome.state_norm_squared.sqrt() + tol);
            if decrease <= self.config.relative_cost_tolerance * (cost + decrease) {
                report.termination = Termination::CostConverged;
                break;
            }
            if step_small {
                report.termination = Termination::StepConverged;
                break;
            }
            if stage.abort.is_some_and(|a| a.load(Ordering::Acquire)) {
                report.termination = Termination::Aborted;
                break;
            }
        }
        report.final_cost = cost;
        Ok(report)
    }
}
