//! The step pass: back-substitutes the point steps
//! `δp = V⁻¹(−b_p − Σ Wᵀ δc)` and evaluates the cost at the candidate state.

use nalgebra::{Vector3, Vector6};

use super::chunk::{PassInputs, PointChunk};
use super::layout::FIXED_POSE;
use crate::optim::damping::marquardt_scale;
use crate::optim::reprojection::{kernel_cost_and_weight, observation_chi2, PoseMatrix};

impl PointChunk {
    /// Computes the candidate points from the pose steps (by free pose) and
    /// the cost of the chunk's active observations at the candidate poses.
    pub fn step_and_evaluate(
        &mut self,
        inputs: &PassInputs<'_>,
        pose_steps: &[Vector6<f64>],
        candidate_poses: &[PoseMatrix],
    ) {
        let mut cost = 0.0;
        let mut step_norm_squared = 0.0;
        let mut step_scaled_norm_squared = 0.0;
        let mut step_dot_gradient = 0.0;
        let mut state_norm_squared = 0.0;
        let obs_start = self.observations.start;
        for (local_point, point) in self.points.clone().enumerate() {
            let bp = self.point_gradient[local_point];
            let mut rhs: Vector3<f64> = -bp;
            let range = inputs.layout.point_observations(point);
            for k in range.clone() {
                let free = inputs.layout.observations[k].free_pose;
                if free != FIXED_POSE && inputs.active[k] {
                    rhs -= self.pose_point[k - obs_start].tr_mul(&pose_steps[free as usize]);
                }
            }
            let step = self.point_inverse[local_point] * rhs;
            step_norm_squared += step.norm_squared();
            let scale = self.point_hessian[local_point]
                .diagonal()
                .map(marquardt_scale);
            step_scaled_norm_squared += step.component_mul(&scale).dot(&step);
            step_dot_gradient += step.dot(&bp);
            let current = inputs.points[point];
            state_norm_squared += current.norm_squared();
            let candidate = current + step;
            self.candidate_points[local_point] = candidate;
            for k in range {
                if !inputs.active[k] {
                    continue;
                }
                let o = &inputs.layout.observations[k];
                let p_cam = candidate_poses[o.pose as usize].transform(&candidate);
                let chi2 = observation_chi2(inputs.camera, &p_cam, &o.obs);
                let delta = inputs.robust.then(|| o.obs.huber_delta());
                cost += kernel_cost_and_weight(chi2, delta).0;
            }
        }
        self.sums.cost = cost;
        self.sums.step_norm_squared = step_norm_squared;
        self.sums.step_scaled_norm_squared = step_scaled_norm_squared;
        self.sums.step_dot_gradient = step_dot_gradient;
        self.sums.state_norm_squared = state_norm_squared;
    }
}
