//! Lie groups for poses: [`Se3`] (rigid motions) and [`Sim3`] (similarities).
//!
//! Both implement [`LieGroup`], so one generic test suite checks the group
//! axioms, `exp`/`log` round trips, the adjoint identity and every analytic
//! Jacobian against numeric differences (`tests/optim_lie.rs`).
//!
//! Conventions (g2o's, which ORB-SLAM3 uses):
//! - tangent vectors put rotation first: SE3 `[ω, υ]`, Sim3 `[ω, υ, σ]`
//!   with `σ = ln(scale)`;
//! - perturbations are applied on the left: `exp(δ) · g`;
//! - a group element acts on points as `p ↦ s·R·p + t` (`s = 1` for SE3).

mod jacobian;
mod se3;
mod sim3;
mod so3;

use nalgebra::{Matrix3x4, Matrix4, SMatrix, SVector, Vector3};

pub use jacobian::{left_jacobian_from_ad, left_jacobian_inverse_from_ad};
pub use se3::Se3;
pub use sim3::Sim3;
pub use so3::{hat, so3_exp, so3_left_jacobian, so3_left_jacobian_inverse, so3_log};

/// A matrix Lie group acting on 3-D points, with `N` degrees of freedom.
pub trait LieGroup<const N: usize>: Copy + std::fmt::Debug + PartialEq {
    /// The identity element.
    fn identity() -> Self;
    /// Group composition `self · other`.
    fn compose(&self, other: &Self) -> Self;
    /// The inverse element.
    fn inverse(&self) -> Self;
    /// The exponential map from the tangent space (see the module docs for the order).
    fn exp(tangent: &SVector<f64, N>) -> Self;
    /// The logarithm, inverse of [`LieGroup::exp`] for rotations below π.
    fn log(&self) -> SVector<f64, N>;
    /// The adjoint matrix: `g · exp(ξ) · g⁻¹ = exp(Ad_g ξ)`.
    fn adjoint(&self) -> SMatrix<f64, N, N>;
    /// The Lie bracket as a matrix: `ad(ξ) η = [ξ, η]`.
    fn small_adjoint(tangent: &SVector<f64, N>) -> SMatrix<f64, N, N>;
    /// The 4×4 matrix of a tangent vector (an element of the Lie algebra).
    fn hat(tangent: &SVector<f64, N>) -> Matrix4<f64>;
    /// The homogeneous 4×4 matrix of the element.
    fn to_matrix(&self) -> Matrix4<f64>;
    /// Applies the element to a point: `s·R·p + t`.
    fn transform_point(&self, point: &Vector3<f64>) -> Vector3<f64>;
    /// Jacobian of `exp(δ) · g · p` with respect to `δ` at `δ = 0` (3×N).
    fn transform_jacobian(&self, point: &Vector3<f64>) -> SMatrix<f64, 3, N>;

    /// Left Jacobian `J_l(ξ)`: `exp(ξ + δ) ≈ exp(J_l(ξ) δ) · exp(ξ)`.
    fn left_jacobian(tangent: &SVector<f64, N>) -> SMatrix<f64, N, N> {
        left_jacobian_from_ad(&Self::small_adjoint(tangent))
    }
    /// Inverse left Jacobian: `log(exp(δ) · exp(ξ)) ≈ ξ + J_l⁻¹(ξ) δ`.
    fn left_jacobian_inverse(tangent: &SVector<f64, N>) -> SMatrix<f64, N, N> {
        left_jacobian_inverse_from_ad(&Self::small_adjoint(tangent))
    }
    /// Right Jacobian `J_r(ξ) = J_l(-ξ)`: `exp(ξ + δ) ≈ exp(ξ) · exp(J_r(ξ) δ)`.
    fn right_jacobian(tangent: &SVector<f64, N>) -> SMatrix<f64, N, N> {
        Self::left_jacobian(&(-tangent))
    }
    /// Inverse right Jacobian: `log(exp(ξ) · exp(δ)) ≈ ξ + J_r⁻¹(ξ) δ`.
    fn right_jacobian_inverse(tangent: &SVector<f64, N>) -> SMatrix<f64, N, N> {
        Self::left_jacobian_inverse(&(-tangent))
    }
    /// Applies a left perturbation: `exp(δ) · self`.
    fn perturb_left(&self, delta: &SVector<f64, N>) -> Self {
        Self::exp(delta).compose(self)
    }
    /// The top three rows of [`LieGroup::to_matrix`].
    fn to_matrix3x4(&self) -> Matrix3x4<f64> {
        self.to_matrix().fixed_rows::<3>(0).into_owned()
    }
}
