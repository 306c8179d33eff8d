//! The edge residual `e = log(Z_ij · T_i · T_j⁻¹)` and its analytic Jacobians.
//!
//! Nodes are world→camera poses `T_i` (ORB-SLAM3's `S_iw`); the measurement
//! of edge `i → j` is the relative transform `Z_ij ≈ T_j · T_i⁻¹` (ORB-SLAM3's
//! `S_ji`), so the residual is ORB-SLAM3's `log(S_ji · S_iw · S_jw⁻¹)`.
//!
//! With left perturbations `T ← exp(δ) · T`, writing `E = Z · T_i · T_j⁻¹`
//! and `e = log E`:
//! - `Z · exp(δ_i) · T_i · T_j⁻¹ = exp(Ad_Z δ_i) · E`, so
//!   `∂e/∂δ_i = J_l⁻¹(e) · Ad_Z`;
//! - `Z · T_i · T_j⁻¹ · exp(−δ_j) = E · exp(−δ_j)`, so `∂e/∂δ_j = −J_r⁻¹(e)`.

use nalgebra::{SMatrix, SVector};

use crate::optim::lie::LieGroup;

/// The residual of one edge and its Jacobians with respect to left
/// perturbations of the `from` and `to` nodes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EdgeLinearisation<const N: usize> {
    /// `e = log(Z_ij · T_i · T_j⁻¹)`.
    pub residual: SVector<f64, N>,
    /// `∂e/∂δ_i` (the `from` node).
    pub jacobian_from: SMatrix<f64, N, N>,
    /// `∂e/∂δ_j` (the `to` node).
    pub jacobian_to: SMatrix<f64, N, N>,
}

/// `e = log(Z_ij · T_i · T_j⁻¹)`; zero when `Z_ij = T_j · T_i⁻¹`.
pub fn edge_residual<G: LieGroup<N>, const N: usize>(
    measurement: &G,
    from: &G,
    to: &G,
) -> SVector<f64, N> {
    measurement.compose(from).compose(&to.inverse()).log()
}

/// The residual and both analytic Jacobians (see the module docs).
pub fn linearise_edge<G: LieGroup<N>, const N: usize>(
    measurement: &G,
    from: &G,
    to: &G,
) -> EdgeLinearisation<N> {
    linearise_edge_with_adjoint(measurement, &measurement.adjoint(), from, to)
}

/// [`linearise_edge`] with `Ad_Z` supplied (it is constant per edge, so the
/// solver computes it once).
pub fn linearise_edge_with_adjoint<G: LieGroup<N>, const N: usize>(
    measurement: &G,
    measurement_adjoint: &SMatrix<f64, N, N>,
    from: &G,
    to: &G,
) -> EdgeLinearisation<N> {
    let error_element = measurement.compose(from).compose(&to.inverse());
    let residual = error_element.log();
    let (left_inverse, right_inverse) = match inverse_jacobians_by_series::<G, N>(&residual) {
        Some(pair) => pair,
        // J_l(ξ) = Ad_exp(ξ) · J_r(ξ), so J_r⁻¹(ξ) = J_l⁻¹(ξ) · Ad_E with E = exp(e).
        None => {
            let left_inverse = G::left_jacobian_inverse(&residual);
            (left_inverse, left_inverse * error_element.adjoint())
        }
    };
    EdgeLinearisation {
        residual,
        jacobian_from: left_inverse * measurement_adjoint,
        jacobian_to: -right_inverse,
    }
}

/// `B_{2k} / (2k)!` for `k = 1..=10`: the even terms of the series
/// `J_l⁻¹(ξ) = Σ Bₙ/n! · ad(ξ)ⁿ` (every odd term but `n = 1` vanishes).
const BERNOULLI_EVEN_OVER_FACTORIAL: [f64; 10] = [
    1.0 / 12.0,
    -1.0 / 720.0,
    1.0 / 30_240.0,
    -1.0 / 1_209_600.0,
    1.0 / 47_900_160.0,
    -691.0 / 1_307_674_368_000.0,
    1.0 / 74_724_249_600.0,
    -3617.0 / 10_670_622_842_880_000.0,
    43_867.0 / 5_109_094_217_170_944_000.0,
    -174_611.0 / 802_857_662_698_291_200_000.0,
];

/// Below this Frobenius norm of `ad(ξ)` (an upper bound on its spectral
/// radius) the Bernoulli series converges by a factor `(1/2π)² ≈ 0.025` per
/// term, so ten terms reach rounding.
const SERIES_NORM_LIMIT: f64 = 1.0;

/// `(J_l⁻¹(ξ), J_r⁻¹(ξ))`.
///
/// For small `ξ` both come from one series (see
/// [`inverse_jacobians_by_series`]); larger `ξ` use
/// [`LieGroup::left_jacobian_inverse`] / [`LieGroup::right_jacobian_inverse`].
pub fn inverse_jacobians<G: LieGroup<N>, const N: usize>(
    tangent: &SVector<f64, N>,
) -> (SMatrix<f64, N, N>, SMatrix<f64, N, N>) {
    inverse_jacobians_by_series::<G, N>(tangent).unwrap_or_else(|| {
        (
            G::left_jacobian_inverse(tangent),
            G::right_jacobian_inverse(tangent),
        )
    })
}

/// `(J_l⁻¹(ξ), J_r⁻¹(ξ))` from the Bernoulli series, or `None` when
/// `‖ad(ξ)‖_F ≥ 1` (the ten tabulated terms would not reach rounding).
///
/// `J_l⁻¹ = I − ½ad + S` and `J_r⁻¹ = J_l⁻¹(−ξ) = I + ½ad + S`, with `S` the
/// even terms `Σ B_{2k}/(2k)! · ad^{2k}`, shared by both.
pub fn inverse_jacobians_by_series<G: LieGroup<N>, const N: usize>(
    tangent: &SVector<f64, N>,
) -> Option<(SMatrix<f64, N, N>, SMatrix<f64, N, N>)> {
    let ad = G::small_adjoint(tangent);
    if ad.norm() >= SERIES_NORM_LIMIT {
        return None;
    }
    let ad_squared = ad * ad;
    let mut power = ad_squared;
    let mut even = SMatrix::<f64, N, N>::identity();
    for coefficient in BERNOULLI_EVEN_OVER_FACTORIAL {
        let term = power * coefficient;
        even += term;
        if term.amax() <= f64::EPSILON * 1e-2 {
            break;
        }
        power *= ad_squared;
    }
    let half_ad = ad * 0.5;
    Some((even - half_ad, even + half_ad))
}
