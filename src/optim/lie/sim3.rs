//! Sim(3): similarities `p ↦ s·R·p + t`, tangent `[ω, υ, σ]` with `s = e^σ`.

use nalgebra::{Matrix3, Matrix4, SMatrix, SVector, UnitQuaternion, Vector3};

use super::jacobian::power_series;
use super::se3::Se3;
use super::so3::{hat, rotation_matrix, so3_exp, so3_log, unit_product};
use super::LieGroup;

/// A similarity transform `p ↦ s·R·p + t`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sim3 {
    /// The rotation `R`.
    pub rotation: UnitQuaternion<f64>,
    /// The translation `t`.
    pub translation: Vector3<f64>,
    /// The scale `s > 0`.
    pub scale: f64,
}

impl Sim3 {
    /// A similarity from its parts.
    pub fn new(rotation: UnitQuaternion<f64>, translation: Vector3<f64>, scale: f64) -> Self {
        Self {
            rotation,
            translation,
            scale,
        }
    }

    /// A rigid motion as a similarity of scale 1.
    pub fn from_se3(pose: &Se3) -> Self {
        Self::new(pose.rotation, pose.translation, 1.0)
    }

    /// The rigid motion with the same rotation and `t / s`, as ORB-SLAM3 does
    /// when it turns corrected Sim3 poses back into keyframe poses.
    pub fn to_se3_unscaled(&self) -> Se3 {
        Se3::new(self.rotation, self.translation / self.scale)
    }

    /// The rotation matrix `R`.
    pub fn rotation_matrix(&self) -> Matrix3<f64> {
        rotation_matrix(&self.rotation)
    }
}

impl std::ops::Mul for Sim3 {
    type Output = Sim3;
    fn mul(self, rhs: Sim3) -> Sim3 {
        self.compose(&rhs)
    }
}

/// `W(ω, σ) = Σ_{n≥0} (ω^ + σI)ⁿ / (n+1)!`, with `t = W υ` in Sim(3)'s exp.
///
/// The closed form (Strasdat's thesis) loses digits when either the angle or
/// σ is small but not zero; the series is exact to rounding everywhere and
/// costs a few dozen 3×3 products.
fn translation_jacobian(w: &Vector3<f64>, sigma: f64) -> Matrix3<f64> {
    power_series(&(hat(w) + Matrix3::identity() * sigma), 1)
}

impl LieGroup<7> for Sim3 {
    fn identity() -> Self {
        Self::new(UnitQuaternion::identity(), Vector3::zeros(), 1.0)
    }

    fn compose(&self, other: &Self) -> Self {
        Self::new(
            unit_product(&self.rotation, &other.rotation),
            self.rotation * other.translation * self.scale + self.translation,
            self.scale * other.scale,
        )
    }

    fn inverse(&self) -> Self {
        let r_inv = self.rotation.inverse();
        let s_inv = 1.0 / self.scale;
        Self::new(r_inv, -(r_inv * self.translation) * s_inv, s_inv)
    }

    fn exp(tangent: &SVector<f64, 7>) -> Self {
        let w: Vector3<f64> = tangent.fixed_rows::<3>(0).into_owned();
        let v: Vector3<f64> = tangent.fixed_rows::<3>(3).into_owned();
        let sigma = tangent[6];
        Self::new(
            so3_exp(&w),
            translation_jacobian(&w, sigma) * v,
            sigma.exp(),
        )
    }

    fn log(&self) -> SVector<f64, 7> {
        let w = so3_log(&self.rotation);
        let sigma = self.scale.ln();
        let v = translation_jacobian(&w, sigma)
            .try_inverse()
            .map_or_else(Vector3::zeros, |w_inv| w_inv * self.translation);
        SVector::<f64, 7>::from_column_slice(&[w.x, w.y, w.z, v.x, v.y, v.z, sigma])
    }

    fn adjoint(&self) -> SMatrix<f64, 7, 7> {
        let r = self.rotation_matrix();
        let mut ad = SMatrix::<f64, 7, 7>::zeros();
        ad.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
        ad.fixed_view_mut::<3, 3>(3, 0)
            .copy_from(&(hat(&self.translation) * r));
        ad.fixed_view_mut::<3, 3>(3, 3).copy_from(&(r * self.scale));
        ad.fixed_view_mut::<3, 1>(3, 6)
            .copy_from(&(-self.translation));
        ad[(6, 6)] = 1.0;
        ad
    }

    fn small_adjoint(tangent: &SVector<f64, 7>) -> SMatrix<f64, 7, 7> {
        let w_hat = hat(&tangent.fixed_rows::<3>(0).into_owned());
        let v: Vector3<f64> = tangent.fixed_rows::<3>(3).into_owned();
        let sigma = tangent[6];
        let mut ad = SMatrix::<f64, 7, 7>::zeros();
        ad.fixed_view_mut::<3, 3>(0, 0).copy_from(&w_hat);
        ad.fixed_view_mut::<3, 3>(3, 0).copy_from(&hat(&v));
        ad.fixed_view_mut::<3, 3>(3, 3)
            .copy_from(&(w_hat + Matrix3::identity() * sigma));
        ad.fixed_view_mut::<3, 1>(3, 6).copy_from(&(-v));
        ad
    }

    fn hat(tangent: &SVector<f64, 7>) -> Matrix4<f64> {
        let mut m = Matrix4::zeros();
        let w_hat = hat(&tangent.fixed_rows::<3>(0).into_owned());
        m.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(w_hat + Matrix3::identity() * tangent[6]));
        m.fixed_view_mut::<3, 1>(0, 3)
            .copy_from(&tangent.fixed_rows::<3>(3));
        m
    }

    fn to_matrix(&self) -> Matrix4<f64> {
        let mut m = Matrix4::identity();
        m.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(self.rotation_matrix() * self.scale));
        m.fixed_view_mut::<3, 1>(0, 3).copy_from(&self.translation);
        m
    }

    fn transform_point(&self, point: &Vector3<f64>) -> Vector3<f64> {
        self.rotation * point * self.scale + self.translation
    }

    fn transform_jacobian(&self, point: &Vector3<f64>) -> SMatrix<f64, 3, 7> {
        let q = self.transform_point(point);
        let mut j = SMatrix::<f64, 3, 7>::zeros();
        j.fixed_view_mut::<3, 3>(0, 0).copy_from(&(-hat(&q)));
        j.fixed_view_mut::<3, 3>(0, 3)
            .copy_from(&Matrix3::identity());
        j.fixed_view_mut::<3, 1>(0, 6).copy_from(&q);
        j
    }
}
