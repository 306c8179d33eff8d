//! The reprojection model shared by pose-only optimisation and local bundle
//! adjustment: the rectified stereo pinhole camera, observations with their
//! information weights, residuals with analytic Jacobians (left
//! perturbation of `T_cw`, tangent `[ω, υ]`) and the Huber kernel with
//! ORB-SLAM3's χ² thresholds.
//!
//! Residuals are `predicted − measured`; the χ² of an observation is
//! `information · |residual|²`. Both solvers assemble their normal
//! equations from [`CameraSpaceTerms`], which holds the only projection
//! derivative in the crate; the pose and point blocks are obtained from it by
//! the chain rule (`∂p_c/∂δ = [−p_c^, I]`, `∂p_c/∂X = R`).

mod camera;
mod linearise;
mod observation;
mod robust;
mod terms;

pub use camera::PinholeStereo;
pub use linearise::{linearise_mono, linearise_stereo, ReprojectionJacobians};
pub use observation::{inv_level_sigma2, Measurement, Observation};
pub use robust::{huber_cost, huber_weight, kernel_cost_and_weight, CHI2_MONO_95, CHI2_STEREO_95};
pub use terms::{observation_chi2, CameraSpaceTerms, PoseMatrix};

#[cfg(test)]
mod tests;
