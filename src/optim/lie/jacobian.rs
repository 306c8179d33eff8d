//! Left Jacobians of any matrix Lie group from its small adjoint `ad(ξ)`.
//!
//! `J_l(ξ) = Σ ad(ξ)ⁿ / (n+1)!`, a series that converges for every `ξ` and
//! needs no special cases near zero. Its inverse is computed by inverting the
//! (small, dense) matrix, which is exact wherever `J_l` is invertible, i.e.
//! for rotation angles other than non-zero multiples of 2π.

use nalgebra::SMatrix;

/// `J_l(ξ) = Σ_{n≥0} ad(ξ)ⁿ / (n+1)!`, summed until the terms vanish.
pub fn left_jacobian_from_ad<const N: usize>(ad: &SMatrix<f64, N, N>) -> SMatrix<f64, N, N> {
    power_series(ad, 1)
}

/// `Σ_{n≥0} Mⁿ / (n+k)! · k!`: with `k = 1` the left Jacobian, `k = 0` the exponential.
pub(super) fn power_series<const N: usize>(
    m: &SMatrix<f64, N, N>,
    offset: usize,
) -> SMatrix<f64, N, N> {
    let mut sum = SMatrix::<f64, N, N>::identity();
    let mut term = SMatrix::<f64, N, N>::identity();
    for n in 1..80 {
        term = term * m / (n + offset) as f64;
        sum += term;
        if term.amax() <= f64::EPSILON * 1e-2 * sum.amax() {
            break;
        }
    }
    sum
}

/// `J_l⁻¹(ξ)`, the inverse of [`left_jacobian_from_ad`]. Where `J_l` is
/// singular (rotation angle a non-zero multiple of 2π, never met in
/// optimisation) it falls back to the first-order `I − ½ ad(ξ)`.
pub fn left_jacobian_inverse_from_ad<const N: usize>(
    ad: &SMatrix<f64, N, N>,
) -> SMatrix<f64, N, N> {
    left_jacobian_from_ad(ad)
        .try_inverse()
        .unwrap_or_else(|| SMatrix::<f64, N, N>::identity() - ad * 0.5)
}
