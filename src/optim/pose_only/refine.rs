//! Levenberg–Marquardt on the 6×6 normal equations of one pose.

use nalgebra::{Matrix6, Vector6};

use super::PoseCorrespondence;
use crate::optim::damping::{gain_ratio, marquardt_scale, predicted_decrease, NielsenDamping};
use crate::optim::reprojection::{
    huber_cost, huber_weight, observation_chi2, CameraSpaceTerms, PinholeStereo, PoseMatrix,
};
use crate::optim::{LieGroup, Se3};

/// Tries per iteration before giving up on finding a decrease (g2o's 10).
const MAX_TRIES: usize = 10;

/// What one refinement optimises: the active correspondences, with or without Huber.
pub(super) struct RefineProblem<'a> {
    pub camera: &'a PinholeStereo,
    pub correspondences: &'a [PoseCorrespondence],
    pub active: &'a [bool],
    pub robust: bool,
}

impl RefineProblem<'_> {
    fn kernel(&self, chi2: f64, delta: f64) -> f64 {
        if self.robust {
            huber_cost(chi2, delta)
        } else {
            chi2
        }
    }

    fn cost(&self, pose: &Se3) -> f64 {
        let pm = PoseMatrix::from_se3(pose);
        self.correspondences
            .iter()
            .zip(self.active)
            .filter(|(_, &a)| a)
            .map(|(c, _)| {
                let chi2 = observation_chi2(self.camera, &pm.transform(&c.point), &c.observation);
                self.kernel(chi2, c.observation.huber_delta())
            })
            .sum()
    }

    /// Gauss–Newton (IRLS) Hessian, gradient and cost at `pose`.
    fn linearise(&self, pose: &Se3) -> (Matrix6<f64>, Vector6<f64>, f64) {
        let pm = PoseMatrix::from_se3(pose);
        let (mut h, mut b, mut cost) = (Matrix6::zeros(), Vector6::zeros(), 0.0);
        for (c, _) in self
            .correspondences
            .iter()
            .zip(self.active)
            .filter(|(_, &a)| a)
        {
            let terms =
                CameraSpaceTerms::evaluate(self.camera, &pm.transform(&c.point), &c.observation);
            let delta = c.observation.huber_delta();
            cost += self.kernel(terms.chi2, delta);
            let weight = if self.robust {
                huber_weight(terms.chi2, delta)
            } else {
                1.0
            };
            let terms = terms.scaled(weight);
            h += terms.pose_hessian();
            b += terms.pose_gradient();
        }
        (h, b, cost)
    }

    /// Runs up to `iterations` LM iterations from `pose`; returns the refined pose.
    pub fn refine(&self, pose: Se3, iterations: usize, relative_tolerance: f64) -> Se3 {
        let mut pose = pose;
        let mut damping: Option<NielsenDamping> = None;
        for _ in 0..iterations {
            let (h, b, cost) = self.linearise(&pose);
            let damping = damping
                .get_or_insert_with(|| NielsenDamping::new(NielsenDamping::DEFAULT_INITIAL_MU));
            let scale = h.diagonal().map(marquardt_scale);
            let mut accepted = None;
            for _ in 0..MAX_TRIES {
                let mu = damping.mu();
                let step = (h + Matrix6::from_diagonal(&(scale * mu)))
                    .cholesky()
                    .map(|c| c.solve(&(-b)));
                let Some(step) = step else {
                    damping.reject();
                    continue;
                };
                let candidate = pose.perturb_left(&step);
                let new_cost = self.cost(&candidate);
                let scaled_norm = step.component_mul(&scale).dot(&step);
                let predicted = predicted_decrease(mu, scaled_norm, step.dot(&b));
                let rho = gain_ratio(cost, new_cost, predicted);
                if rho > 0.0 {
                    damping.accept(rho);
                    accepted = Some((candidate, new_cost));
                    break;
                }
                damping.reject();
            }
            let Some((candidate, new_cost)) = accepted else {
                break;
            };
            pose = candidate;
            if cost - new_cost <= relative_tolerance * cost {
                break;
            }
        }
        pose
    }
}
