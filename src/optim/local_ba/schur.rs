//! The Schur pass: eliminates each point from the damped normal equations,
//! accumulating this chunk's part of the reduced camera system
//! `S = H_cc + μD − Σ W V⁻¹ Wᵀ`, `s = −b_c + Σ W V⁻¹ b_p`
//! (the `−Σ…` and `+Σ…` parts; upper block triangle only).

use nalgebra::{Matrix3, Matrix6};

use crate::optim::damping::marquardt_scale;

use super::chunk::{PassInputs, PointChunk, ScaledBlock};
use super::layout::FIXED_POSE;

impl PointChunk {
    /// Reduces with damping `mu`; sets `sums.singular` when a point block fails to invert.
    pub fn reduce(&mut self, inputs: &PassInputs<'_>, mu: f64) {
        self.reduced.fill(0.0);
        self.reduced_rhs.fill(0.0);
        self.sums.singular = false;
        let obs_start = self.observations.start;
        for (local_point, point) in self.points.clone().enumerate() {
            let hpp = &self.point_hessian[local_point];
            let damped = hpp + Matrix3::from_diagonal(&(hpp.diagonal().map(marquardt_scale) * mu));
            let Some(inverse) = damped.try_inverse() else {
                self.sums.singular = true;
                self.point_inverse[local_point] = Matrix3::zeros();
                continue;
            };
            self.point_inverse[local_point] = inverse;
            let bp = self.point_gradient[local_point];
            self.scaled.clear();
            for k in inputs.layout.point_observations(point) {
                let free = inputs.layout.observations[k].free_pose;
                if free == FIXED_POSE || !inputs.active[k] {
                    continue;
                }
                let local_observation = k - obs_start;
                let block = self.pose_point[local_observation] * inverse;
                let free = free as usize;
                let mut rhs = self.reduced_rhs.fixed_rows_mut::<6>(6 * free);
                rhs += block * bp;
                self.scaled.push(ScaledBlock {
                    free_pose: free,
                    local_observation,
                    block,
                });
            }
            for (i, yi) in self.scaled.iter().enumerate() {
                for yj in &self.scaled[i..] {
                    let wj = &self.pose_point[yj.local_observation];
                    let product: Matrix6<f64> = yi.block * wj.transpose();
                    let (a, b) = (yi.free_pose, yj.free_pose);
                    if a < b {
                        let mut view = self.reduced.fixed_view_mut::<6, 6>(6 * a, 6 * b);
                        view -= product;
                    } else if a > b {
                        let mut view = self.reduced.fixed_view_mut::<6, 6>(6 * b, 6 * a);
                        view -= product.transpose();
                    } else if yi.local_observation == yj.local_observation {
                        let mut view = self.reduced.fixed_view_mut::<6, 6>(6 * a, 6 * a);
                        view -= product;
                    } else {
                        // Two observations of one point from one pose.
                        let mut view = self.reduced.fixed_view_mut::<6, 6>(6 * a, 6 * a);
                        view -= product + product.transpose();
                    }
                }
            }
        }
    }
}
