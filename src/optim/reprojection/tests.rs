//! Analytic Jacobians against central differences (step 1e-6, tolerance
//! 1e-5 relative to the Jacobian's largest entry), the normal-equation
//! blocks against explicit `JᵀΩJ` products (1e-9 relative) and the Huber
//! weight against the derivative of the Huber cost.

use nalgebra::{SMatrix, SVector, UnitQuaternion, Vector2, Vector3, Vector6};

use super::*;
use crate::optim::{LieGroup, Se3};

const STEP: f64 = 1e-6;

fn camera() -> PinholeStereo {
    PinholeStereo::new(718.856, 720.1, 607.19, 185.21, 386.14)
}

fn pose() -> Se3 {
    Se3::new(
        UnitQuaternion::from_euler_angles(0.1, -0.2, 0.3),
        Vector3::new(0.3, -0.1, 0.5),
    )
}

fn numeric<const R: usize, const N: usize>(
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

fn assert_close<const R: usize, const N: usize>(
    a: &SMatrix<f64, R, N>,
    b: &SMatrix<f64, R, N>,
    rel: f64,
    what: &str,
) {
    let scale = b.amax().max(1.0);
    let err = (a - b).amax();
    assert!(err <= rel * scale, "{what}: error {err:e}\n{a}\n{b}");
}

fn world_point() -> Vector3<f64> {
    // In front of the camera of `pose()`.
    pose()
        .inverse()
        .transform_point(&Vector3::new(1.2, -0.7, 8.0))
}

#[test]
fn mono_jacobians_match_central_differences() {
    let (cam, pose, point) = (camera(), pose(), world_point());
    let measured = Vector2::new(640.0, 100.0);
    let lin = linearise_mono(&cam, &pose, &point, &measured);
    let r = |p: &Se3, x: &Vector3<f64>| cam.project(&p.transform_point(x)) - measured;
    let d_pose = numeric(|d: &Vector6<f64>| r(&pose.perturb_left(d), &point));
    let d_point = numeric(|d: &Vector3<f64>| r(&pose, &(point + d)));
    assert_close(&lin.residual, &r(&pose, &point), 1e-12, "mono residual");
    assert_close(&lin.d_pose, &d_pose, 1e-5, "mono d_pose");
    assert_close(&lin.d_point, &d_point, 1e-5, "mono d_point");
}

#[test]
fn stereo_jacobians_match_central_differences() {
    let (cam, pose, point) = (camera(), pose(), world_point());
    let measured = Vector3::new(640.0, 100.0, 600.0);
    let lin = linearise_stereo(&cam, &pose, &point, &measured);
    let r = |p: &Se3, x: &Vector3<f64>| cam.project_stereo(&p.transform_point(x)) - measured;
    let d_pose = numeric(|d: &Vector6<f64>| r(&pose.perturb_left(d), &point));
    let d_point = numeric(|d: &Vector3<f64>| r(&pose, &(point + d)));
    assert_close(&lin.residual, &r(&pose, &point), 1e-12, "stereo residual");
    assert_close(&lin.d_pose, &d_pose, 1e-5, "stereo d_pose");
    assert_close(&lin.d_point, &d_point, 1e-5, "stereo d_point");
}

fn check_blocks<const R: usize>(lin: &ReprojectionJacobians<R>, obs: &Observation) {
    let (cam, pose, point) = (camera(), pose(), world_point());
    let pm = PoseMatrix::from_se3(&pose);
    let weight = 0.37;
    let terms = CameraSpaceTerms::evaluate(&cam, &pm.transform(&point), obs).scaled(weight);
    let w = weight * obs.information;
    let tol = 1e-9;
    assert!((terms.chi2 - obs.information * lin.residual.norm_squared()).abs() < 1e-9);
    assert_close(
        &terms.pose_hessian(),
        &(lin.d_pose.transpose() * lin.d_pose * w),
        tol,
        "pose hessian",
    );
    assert_close(
        &terms.pose_gradient(),
        &(lin.d_pose.transpose() * lin.residual * w),
        tol,
        "pose gradient",
    );
    assert_close(
        &terms.pose_point(&pm.rotation),
        &(lin.d_pose.transpose() * lin.d_point * w),
        tol,
        "pose-point block",
    );
    assert_close(
        &terms.point_hessian(&pm.rotation),
        &(lin.d_point.transpose() * lin.d_point * w),
        tol,
        "point hessian",
    );
    assert_close(
        &terms.point_gradient(&pm.rotation),
        &(lin.d_point.transpose() * lin.residual * w),
        tol,
        "point gradient",
    );
    let chi2 = observation_chi2(&cam, &pm.transform(&point), obs);
    assert!((chi2 - terms.chi2).abs() < 1e-9);
}

#[test]
fn normal_blocks_equal_explicit_products() {
    let (cam, pose, point) = (camera(), pose(), world_point());
    let mono = Observation::mono(640.0, 100.0, inv_level_sigma2(1.2, 2));
    let stereo = Observation::stereo(640.0, 100.0, 600.0, inv_level_sigma2(1.2, 1));
    let Measurement::Mono(m) = mono.measurement else {
        unreachable!()
    };
    let Measurement::Stereo(s) = stereo.measurement else {
        unreachable!()
    };
    check_blocks(&linearise_mono(&cam, &pose, &point, &m), &mono);
    check_blocks(&linearise_stereo(&cam, &pose, &point, &s), &stereo);
}

#[test]
fn huber_weight_is_the_derivative_of_huber_cost() {
    let delta = CHI2_MONO_95.sqrt();
    for chi2 in [0.1, 1.0, 5.9, 6.1, 30.0, 1e4] {
        let h = 1e-6 * chi2;
        let numeric = (huber_cost(chi2 + h, delta) - huber_cost(chi2 - h, delta)) / (2.0 * h);
        assert!(
            (numeric - huber_weight(chi2, delta)).abs() < 1e-6,
            "chi2 {chi2}"
        );
    }
    assert_eq!(huber_cost(4.0, delta), 4.0);
    assert!(huber_cost(100.0, delta) < 100.0);
}

#[test]
fn observation_thresholds_and_sigmas() {
    let mono = Observation::mono(1.0, 2.0, 1.0);
    let stereo = Observation::stereo(1.0, 2.0, 0.5, 1.0);
    assert_eq!(mono.chi2_threshold(), 5.991);
    assert_eq!(stereo.chi2_threshold(), 7.815);
    assert!((stereo.huber_delta() - 7.815f64.sqrt()).abs() < 1e-15);
    assert!((inv_level_sigma2(1.2, 2) - 1.0 / 1.2f64.powi(4)).abs() < 1e-15);
    assert!(!Observation::mono(f64::NAN, 0.0, 1.0).is_valid());
    assert!(!Observation::mono(0.0, 0.0, 0.0).is_valid());
    assert!(camera().is_valid());
    assert!(!PinholeStereo::new(0.0, 1.0, 0.0, 0.0, 0.0).is_valid());
}
