//! The linearisation pass: per point `H_pp`, `b_p`, per observation
//! `W = J_poseᵀ w Ω J_point`, per chunk the partial `H_cc`, `b_c` and the cost.

use nalgebra::{Matrix3, Matrix6, Vector3, Vector6};

use super::chunk::{ChunkSums, PassInputs, PointChunk};
use super::layout::FIXED_POSE;
use crate::optim::reprojection::{kernel_cost_and_weight, CameraSpaceTerms, PoseMatrix};

impl PointChunk {
    /// Linearises the chunk's active observations at the current state.
    pub fn linearise(&mut self, inputs: &PassInputs<'_>, poses: &[PoseMatrix]) {
        self.pose_hessian.fill(Matrix6::zeros());
        self.pose_gradient.fill(Vector6::zeros());
        let mut sums = ChunkSums::default();
        let obs_start = self.observations.start;
        for (local_point, point) in self.points.clone().enumerate() {
            let x = inputs.points[point];
            let mut hpp = Matrix3::zeros();
            let mut bp = Vector3::zeros();
            for k in inputs.layout.point_observations(point) {
                if !inputs.active[k] {
                    continue;
                }
                let o = &inputs.layout.observations[k];
                let pose = &poses[o.pose as usize];
                let terms = CameraSpaceTerms::evaluate(inputs.camera, &pose.transform(&x), &o.obs);
                let delta = inputs.robust.then(|| o.obs.huber_delta());
                let (cost, weight) = kernel_cost_and_weight(terms.chi2, delta);
                sums.cost += cost;
                let terms = terms.scaled(weight);
                hpp += terms.point_hessian(&pose.rotation);
                bp += terms.point_gradient(&pose.rotation);
                if o.free_pose != FIXED_POSE {
                    let free = o.free_pose as usize;
                    self.pose_point[k - obs_start] = terms.pose_point(&pose.rotation);
                    self.pose_hessian[free] += terms.pose_hessian();
                    self.pose_gradient[free] += terms.pose_gradient();
                }
            }
            self.point_hessian[local_point] = hpp;
            self.point_gradient[local_point] = bp;
        }
        self.sums = sums;
    }
}
