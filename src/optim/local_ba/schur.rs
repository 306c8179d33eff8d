//! The Schur pass: eliminates each point from the damped normal equations,
//! accumulating this chunk's part of the reduced camera system
//! `S = H_cc + μD − Σ W V⁻¹ Wᵀ`, `s = −b_c + Σ W V⁻¹ b_p`
//! (the `−Σ…` and `+Σ…` parts): on the dense path into the upper block
//! triangle of a `6k×6k` matrix, on the sparse path into the lower-triangle
//! values of the [`ReducedPattern`].

use nalgebra::{DMatrix, Matrix3, Matrix6x3};

use crate::optim::damping::marquardt_scale;

use super::blocks::{outer_product, ScaledBlock};
use super::chunk::{PassInputs, PointChunk, ReducedPart};
use super::layout::FIXED_POSE;

impl PointChunk {
    /// Reduces with damping `mu`; sets `sums.singular` when a point block fails to invert.
    pub fn reduce(&mut self, inputs: &PassInputs<'_>, mu: f64) {
        match &mut self.reduced {
            ReducedPart::Dense(matrix) => matrix.fill(0.0),
            ReducedPart::Sparse(values) => values.fill(0.0),
        }
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
            let mut free_observations = 0;
            for k in inputs.layout.point_observations(point) {
                let free = inputs.layout.observations[k].free_pose;
                if free == FIXED_POSE {
                    continue;
                }
                let rank = free_observations;
                free_observations += 1;
                if !inputs.active[k] {
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
                    rank,
                    block,
                });
            }
            let complete = match &mut self.reduced {
                ReducedPart::Dense(matrix) => {
                    subtract_dense(matrix, &self.scaled, &self.pose_point);
                    true
                }
                ReducedPart::Sparse(values) => inputs.reduced_pattern.is_some_and(|pattern| {
                    pattern.subtract_point(
                        values,
                        point,
                        free_observations,
                        &self.scaled,
                        &self.pose_point,
                    )
                }),
            };
            if !complete {
                self.sums.singular = true;
            }
        }
    }
}

/// Subtracts `Y_i W_jᵀ` for every pair of one point's scaled blocks (`i ≤ j`
/// in observation order, so `a ≤ b` for the free poses) from the upper block
/// triangle of the dense `6k×6k` matrix.
fn subtract_dense(
    matrix: &mut DMatrix<f64>,
    scaled: &[ScaledBlock],
    pose_point: &[Matrix6x3<f64>],
) {
    for (i, yi) in scaled.iter().enumerate() {
        for yj in &scaled[i..] {
            let wj = &pose_point[yj.local_observation];
            let product = outer_product(&yi.block, wj);
            let (a, b) = (yi.free_pose, yj.free_pose);
            if a < b {
                let mut view = matrix.fixed_view_mut::<6, 6>(6 * a, 6 * b);
                view -= product;
            } else if a > b {
                let mut view = matrix.fixed_view_mut::<6, 6>(6 * b, 6 * a);
                view -= product.transpose();
            } else if yi.local_observation == yj.local_observation {
                let mut view = matrix.fixed_view_mut::<6, 6>(6 * a, 6 * a);
                view -= product;
            } else {
                // Two observations of one point from one pose.
                let mut view = matrix.fixed_view_mut::<6, 6>(6 * a, 6 * a);
                view -= product + product.transpose();
            }
        }
    }
}
