//! Explicit residuals and Jacobians of one observation, for callers that
//! need the Jacobians themselves (and for checking them against numeric
//! differences). The solvers use [`super::CameraSpaceTerms`], which applies
//! the same chain rule without forming these matrices.

use nalgebra::{SMatrix, SVector, Vector2, Vector3};

use super::camera::PinholeStereo;
use super::terms::{mono_residual, stereo_residual, PoseMatrix};
use crate::optim::lie::hat;
use crate::optim::Se3;

/// The residual of an `R`-dimensional observation and its Jacobians with
/// respect to the pose (left perturbation `exp(δ)·T_cw`, `δ = [ω, υ]`)
/// and the world point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReprojectionJacobians<const R: usize> {
    /// `predicted − measured`.
    pub residual: SVector<f64, R>,
    /// `∂residual/∂δ` (R×6).
    pub d_pose: SMatrix<f64, R, 6>,
    /// `∂residual/∂X_w` (R×3).
    pub d_point: SMatrix<f64, R, 3>,
}

fn chain<const R: usize>(
    residual: SVector<f64, R>,
    d_cam: SMatrix<f64, R, 3>,
    pose: &PoseMatrix,
    p_cam: &Vector3<f64>,
) -> ReprojectionJacobians<R> {
    let mut d_pose = SMatrix::<f64, R, 6>::zeros();
    d_pose
        .fixed_view_mut::<R, 3>(0, 0)
        .copy_from(&(-(d_cam * hat(p_cam))));
    d_pose.fixed_view_mut::<R, 3>(0, 3).copy_from(&d_cam);
    ReprojectionJacobians {
        residual,
        d_pose,
        d_point: d_cam * pose.rotation,
    }
}

/// Residual and Jacobians of a mono observation `measured = (u, v)` of the
/// world point `point` from the camera `pose = T_cw`.
pub fn linearise_mono(
    camera: &PinholeStereo,
    pose: &Se3,
    point: &Vector3<f64>,
    measured: &Vector2<f64>,
) -> ReprojectionJacobians<2> {
    let pose = PoseMatrix::from_se3(pose);
    let p_cam = pose.transform(point);
    let (r, d) = mono_residual(camera, &p_cam, measured);
    chain(r, d, &pose, &p_cam)
}

/// Residual and Jacobians of a stereo observation `measured = (u, v, u_right)`.
pub fn linearise_stereo(
    camera: &PinholeStereo,
    pose: &Se3,
    point: &Vector3<f64>,
    measured: &Vector3<f64>,
) -> ReprojectionJacobians<3> {
    let pose = PoseMatrix::from_se3(pose);
    let p_cam = pose.transform(point);
    let (r, d) = stereo_residual(camera, &p_cam, measured);
    chain(r, d, &pose, &p_cam)
}
