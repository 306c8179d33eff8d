//! One generic test suite for every Lie group in `spslam::optim::lie`
//! (sophus-rs style): group axioms, exp/log round trips, agreement with the
//! matrix exponential, the adjoint identities and every analytic Jacobian
//! against central differences, on random elements.

use nalgebra::{Matrix4, SMatrix, SVector, Vector3};
use proptest::prelude::*;
use spslam::optim::{LieGroup, Se3, Sim3};

/// Tolerance for identities that hold exactly up to rounding.
const EXACT: f64 = 1e-9;
/// Tolerance for analytic vs central-difference Jacobians (step 1e-6).
const NUMERIC: f64 = 1e-6;
const STEP: f64 = 1e-6;

fn matrix_close(a: &Matrix4<f64>, b: &Matrix4<f64>, tol: f64, what: &str) {
    let err = (a - b).amax();
    assert!(err < tol, "{what}: max difference {err:e}\n{a}\n{b}");
}

fn numeric_jacobian<const R: usize, const N: usize>(
    f: impl Fn(&SVector<f64, N>) -> SVector<f64, R>,
) -> SMatrix<f64, R, N> {
    let mut j = SMatrix::<f64, R, N>::zeros();
    for k in 0..N {
        let mut d = SVector::<f64, N>::zeros();
        d[k] = STEP;
        j.set_column(k, &((f(&d) - f(&(-d))) / (2.0 * STEP)));
    }
    j
}

fn jacobian_close<const R: usize, const N: usize>(
    analytic: &SMatrix<f64, R, N>,
    numeric: &SMatrix<f64, R, N>,
    what: &str,
) {
    let err = (analytic - numeric).amax();
    let scale = 1.0 + numeric.amax();
    assert!(
        err < NUMERIC * scale,
        "{what}: analytic vs numeric differ by {err:e}\nanalytic {analytic}\nnumeric {numeric}"
    );
}

/// Every property, for any group `G` with `N` degrees of freedom.
fn check_group<G: LieGroup<N>, const N: usize>(
    xa: SVector<f64, N>,
    xb: SVector<f64, N>,
    xc: SVector<f64, N>,
    p: Vector3<f64>,
) {
    let (a, b, c) = (G::exp(&xa), G::exp(&xb), G::exp(&xc));
    let e = G::identity();

    // Group axioms (compared as matrices).
    matrix_close(&a.compose(&e).to_matrix(), &a.to_matrix(), EXACT, "a·e = a");
    matrix_close(&e.compose(&a).to_matrix(), &a.to_matrix(), EXACT, "e·a = a");
    matrix_close(
        &a.compose(&a.inverse()).to_matrix(),
        &Matrix4::identity(),
        EXACT,
        "a·a⁻¹ = e",
    );
    matrix_close(
        &a.compose(&b).compose(&c).to_matrix(),
        &a.compose(&b.compose(&c)).to_matrix(),
        EXACT,
        "associativity",
    );
    matrix_close(
        &a.compose(&b).to_matrix(),
        &(a.to_matrix() * b.to_matrix()),
        EXACT,
        "compose is the matrix product",
    );
    let ph = a.to_matrix() * p.push(1.0);
    assert!((a.transform_point(&p) - ph.xyz()).amax() < EXACT, "action");

    // exp is the matrix exponential of hat, and log inverts it.
    matrix_close(
        &a.to_matrix(),
        &G::hat(&xa).exp(),
        1e-8,
        "exp = matrix exponential",
    );
    assert!((a.log() - xa).amax() < EXACT, "log(exp(ξ)) = ξ");
    matrix_close(
        &G::exp(&a.log()).to_matrix(),
        &a.to_matrix(),
        EXACT,
        "exp(log(g)) = g",
    );

    // Adjoint identities.
    matrix_close(
        &a.compose(&b).compose(&a.inverse()).to_matrix(),
        &G::exp(&(a.adjoint() * xb)).to_matrix(),
        1e-8,
        "a·exp(ξ)·a⁻¹ = exp(Ad_a ξ)",
    );
    assert!(
        (a.compose(&b).adjoint() - a.adjoint() * b.adjoint()).amax() < 1e-8,
        "Ad(ab) = Ad(a) Ad(b)"
    );
    let bracket = G::hat(&xa) * G::hat(&xb) - G::hat(&xb) * G::hat(&xa);
    matrix_close(
        &G::hat(&(G::small_adjoint(&xa) * xb)),
        &bracket,
        EXACT,
        "ad(ξ)η = [ξ, η]",
    );

    // Jacobians against central differences.
    jacobian_close(
        &b.transform_jacobian(&p),
        &numeric_jacobian(|d| b.perturb_left(d).transform_point(&p)),
        "d(exp(δ)·g·p)/dδ",
    );
    jacobian_close(
        &G::left_jacobian(&xa),
        &numeric_jacobian(|d| G::exp(&(xa + d)).compose(&a.inverse()).log()),
        "left Jacobian",
    );
    jacobian_close(
        &G::left_jacobian_inverse(&xa),
        &numeric_jacobian(|d| G::exp(d).compose(&a).log()),
        "inverse left Jacobian",
    );
    jacobian_close(
        &G::right_jacobian(&xa),
        &numeric_jacobian(|d| a.inverse().compose(&G::exp(&(xa + d))).log()),
        "right Jacobian",
    );
    jacobian_close(
        &G::right_jacobian_inverse(&xa),
        &numeric_jacobian(|d| a.compose(&G::exp(d)).log()),
        "inverse right Jacobian",
    );
}

/// Tangent vectors with rotation angle below 2.5 rad (log's principal range),
/// translations up to 3 and, for Sim3, log-scale within ±0.7.
fn tangent<const N: usize>() -> impl Strategy<Value = SVector<f64, N>> {
    proptest::collection::vec(-1.0f64..1.0, N).prop_map(|v| {
        let mut x = SVector::<f64, N>::from_column_slice(&v);
        let rotation_norm = x.fixed_rows::<3>(0).norm();
        if rotation_norm > 0.0 {
            let angle = 2.5 * rotation_norm / 3f64.sqrt();
            let scaled = x.fixed_rows::<3>(0) * (angle / rotation_norm);
            x.fixed_rows_mut::<3>(0).copy_from(&scaled);
        }
        for k in 3..6 {
            x[k] *= 3.0;
        }
        if N == 7 {
            x[6] *= 0.7;
        }
        x
    })
}

fn point() -> impl Strategy<Value = Vector3<f64>> {
    (-5.0f64..5.0, -5.0f64..5.0, -5.0f64..5.0).prop_map(|(x, y, z)| Vector3::new(x, y, z))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn se3_satisfies_the_lie_group_suite(xa in tangent::<6>(), xb in tangent::<6>(), xc in tangent::<6>(), p in point()) {
        check_group::<Se3, 6>(xa, xb, xc, p);
    }

    #[test]
    fn sim3_satisfies_the_lie_group_suite(xa in tangent::<7>(), xb in tangent::<7>(), xc in tangent::<7>(), p in point()) {
        check_group::<Sim3, 7>(xa, xb, xc, p);
    }
}

/// Near-identity elements exercise the Taylor branches.
#[test]
fn tiny_and_zero_tangents_round_trip() {
    for scale in [0.0, 1e-9, 1e-7, 1e-5] {
        let x6 = SVector::<f64, 6>::from_column_slice(&[1.0, -2.0, 0.5, 0.3, 0.2, -0.1]) * scale;
        check_group::<Se3, 6>(x6, x6 * 0.5, -x6, Vector3::new(1.0, 2.0, 3.0));
        let x7 =
            SVector::<f64, 7>::from_column_slice(&[1.0, -2.0, 0.5, 0.3, 0.2, -0.1, 0.4]) * scale;
        check_group::<Sim3, 7>(x7, x7 * 0.5, -x7, Vector3::new(1.0, 2.0, 3.0));
    }
    // Pure scale and pure rotation with scale: both Taylor branches of W.
    let pure_scale = SVector::<f64, 7>::from_column_slice(&[0.0, 0.0, 0.0, 1.0, 2.0, 3.0, 0.5]);
    check_group::<Sim3, 7>(
        pure_scale,
        -pure_scale,
        pure_scale,
        Vector3::new(-1.0, 0.5, 2.0),
    );
    let no_scale = SVector::<f64, 7>::from_column_slice(&[0.4, 0.1, -0.3, 1.0, 2.0, 3.0, 0.0]);
    check_group::<Sim3, 7>(no_scale, -no_scale, no_scale, Vector3::new(-1.0, 0.5, 2.0));
}

/// Sim3 with unit scale behaves exactly like SE3.
#[test]
fn sim3_with_unit_scale_matches_se3() {
    let x6 = SVector::<f64, 6>::from_column_slice(&[0.3, -0.5, 0.2, 1.0, -2.0, 0.5]);
    let x7 = SVector::<f64, 7>::from_column_slice(&[0.3, -0.5, 0.2, 1.0, -2.0, 0.5, 0.0]);
    let se3 = Se3::exp(&x6);
    let sim3 = Sim3::exp(&x7);
    matrix_close(&se3.to_matrix(), &sim3.to_matrix(), EXACT, "exp");
    assert!((Sim3::from_se3(&se3).log() - x7).amax() < EXACT);
}
