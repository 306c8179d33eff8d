//! The projection derivative in camera coordinates, and the normal-equation
//! blocks of the pose and the point built from it by the chain rule.

use nalgebra::{Matrix2x3, Matrix3, Matrix6, Matrix6x3, Vector2, Vector3, Vector6};

use super::camera::PinholeStereo;
use super::observation::{Measurement, Observation};
use crate::optim::lie::hat;
use crate::optim::Se3;

/// A pose as a rotation matrix and a translation, for transforming many points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseMatrix {
    /// The rotation `R`.
    pub rotation: Matrix3<f64>,
    /// The translation `t`.
    pub translation: Vector3<f64>,
}

impl PoseMatrix {
    /// The matrices of an SE(3) pose.
    pub fn from_se3(pose: &Se3) -> Self {
        Self {
            rotation: pose.rotation_matrix(),
            translation: pose.translation,
        }
    }

    /// `R·p + t`.
    pub fn transform(&self, point: &Vector3<f64>) -> Vector3<f64> {
        self.rotation * point + self.translation
    }
}

/// Mono residual `π(p_c) − m` and its derivative with respect to `p_c`.
pub(super) fn mono_residual(
    camera: &PinholeStereo,
    p_cam: &Vector3<f64>,
    measured: &Vector2<f64>,
) -> (Vector2<f64>, Matrix2x3<f64>) {
    let inv_z = 1.0 / p_cam.z;
    let (x, y) = (p_cam.x * inv_z, p_cam.y * inv_z);
    let residual = Vector2::new(
        camera.fx * x + camera.cx - measured.x,
        camera.fy * y + camera.cy - measured.y,
    );
    let (fxz, fyz) = (camera.fx * inv_z, camera.fy * inv_z);
    let d = Matrix2x3::new(fxz, 0.0, -fxz * x, 0.0, fyz, -fyz * y);
    (residual, d)
}

/// Stereo residual `(u, v, u − bf/z) − m` and its derivative with respect to `p_c`.
pub(super) fn stereo_residual(
    camera: &PinholeStereo,
    p_cam: &Vector3<f64>,
    measured: &Vector3<f64>,
) -> (Vector3<f64>, Matrix3<f64>) {
    let inv_z = 1.0 / p_cam.z;
    let (x, y) = (p_cam.x * inv_z, p_cam.y * inv_z);
    let u = camera.fx * x + camera.cx;
    let residual = Vector3::new(
        u - measured.x,
        camera.fy * y + camera.cy - measured.y,
        u - camera.bf * inv_z - measured.z,
    );
    let (fxz, fyz) = (camera.fx * inv_z, camera.fy * inv_z);
    let bzz = camera.bf * inv_z * inv_z;
    let d = Matrix3::new(
        fxz,
        0.0,
        -fxz * x,
        0.0,
        fyz,
        -fyz * y,
        fxz,
        0.0,
        -fxz * x + bzz,
    );
    (residual, d)
}

/// The χ² (`information · |residual|²`) of an observation of a point at
/// `p_cam` in camera coordinates, without derivatives.
pub fn observation_chi2(camera: &PinholeStereo, p_cam: &Vector3<f64>, obs: &Observation) -> f64 {
    let squared = match &obs.measurement {
        Measurement::Mono(m) => (camera.project(p_cam) - m).norm_squared(),
        Measurement::Stereo(m) => (camera.project_stereo(p_cam) - m).norm_squared(),
    };
    obs.information * squared
}

/// One observation linearised in camera coordinates: with `D = ∂π/∂p_c`,
/// `Ω` the information and `r` the residual, it holds `DᵀΩD` and `DᵀΩr`.
///
/// The pose blocks follow from `J_pose = D·[−p_c^, I]` and the point blocks
/// from `J_point = D·R`; the block methods return them times a scalar weight
/// (the robust IRLS weight) set with [`CameraSpaceTerms::scaled`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraSpaceTerms {
    /// The point in camera coordinates (its `z` is the depth).
    pub camera_point: Vector3<f64>,
    /// `information · |residual|²`.
    pub chi2: f64,
    /// `DᵀΩD`.
    pub hessian: Matrix3<f64>,
    /// `DᵀΩr`.
    pub gradient: Vector3<f64>,
}

impl CameraSpaceTerms {
    /// Linearises `obs` of the point `p_cam` (camera coordinates).
    pub fn evaluate(camera: &PinholeStereo, p_cam: &Vector3<f64>, obs: &Observation) -> Self {
        let info = obs.information;
        let (chi2, hessian, gradient) = match &obs.measurement {
            Measurement::Mono(m) => {
                let (r, d) = mono_residual(camera, p_cam, m);
                let dt = d.transpose();
                (info * r.norm_squared(), dt * d * info, dt * r * info)
            }
            Measurement::Stereo(m) => {
                let (r, d) = stereo_residual(camera, p_cam, m);
                let dt = d.transpose();
                (info * r.norm_squared(), dt * d * info, dt * r * info)
            }
        };
        Self {
            camera_point: *p_cam,
            chi2,
            hessian,
            gradient,
        }
    }

    /// The terms with `DᵀΩD` and `DᵀΩr` multiplied by `weight` (χ² unchanged).
    pub fn scaled(&self, weight: f64) -> Self {
        Self {
            hessian: self.hessian * weight,
            gradient: self.gradient * weight,
            ..*self
        }
    }

    /// The point's depth `z` in the camera.
    pub fn depth(&self) -> f64 {
        self.camera_point.z
    }

    /// `J_poseᵀ Ω J_pose` (6×6).
    pub fn pose_hessian(&self) -> Matrix6<f64> {
        let p = hat(&self.camera_point);
        let a = &self.hessian;
        let ap = a * p;
        let pa = p * a;
        let mut h = Matrix6::zeros();
        h.fixed_view_mut::<3, 3>(0, 0).copy_from(&(-(p * ap)));
        h.fixed_view_mut::<3, 3>(0, 3).copy_from(&pa);
        h.fixed_view_mut::<3, 3>(3, 0).copy_from(&(-ap));
        h.fixed_view_mut::<3, 3>(3, 3).copy_from(a);
        h
    }

    /// `J_poseᵀ Ω r` (6).
    pub fn pose_gradient(&self) -> Vector6<f64> {
        let g = &self.gradient;
        let top = self.camera_point.cross(g);
        Vector6::new(top.x, top.y, top.z, g.x, g.y, g.z)
    }

    /// `J_poseᵀ Ω J_point` (6×3) for the pose's rotation `R`.
    pub fn pose_point(&self, rotation: &Matrix3<f64>) -> Matrix6x3<f64> {
        let ar = self.hessian * rotation;
        let mut w = Matrix6x3::zeros();
        w.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(hat(&self.camera_point) * ar));
        w.fixed_view_mut::<3, 3>(3, 0).copy_from(&ar);
        w
    }

    /// `J_pointᵀ Ω J_point` (3×3) for the pose's rotation `R`.
    pub fn point_hessian(&self, rotation: &Matrix3<f64>) -> Matrix3<f64> {
        rotation.transpose() * self.hessian * rotation
    }

    /// `J_pointᵀ Ω r` (3) for the pose's rotation `R`.
    pub fn point_gradient(&self, rotation: &Matrix3<f64>) -> Vector3<f64> {
        rotation.transpose() * self.gradient
    }
}
