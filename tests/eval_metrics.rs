//! Synthetic trajectories with known answers, and a property test of Umeyama.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;
use spslam::eval::{ate, evaluate, umeyama, Alignment, EvalOptions, Pairing, Trajectory};

/// A wavy 3-D path of `n` poses, 1 m apart along z.
fn path(n: usize) -> Trajectory {
    let poses = (0..n)
        .map(|i| {
            let f = i as f64;
            Isometry3::from_parts(
                Translation3::new(10.0 * (0.01 * f).sin(), 2.0 * (0.03 * f).cos(), f),
                UnitQuaternion::from_euler_angles(0.0, 0.01 * f, 0.0),
            )
        })
        .collect();
    Trajectory::from_poses(poses)
}

#[test]
fn identical_trajectories_have_zero_errors() {
    let t = path(900);
    let r = evaluate(
        &t,
        &t,
        &EvalOptions {
            pairing: Pairing::ByIndex,
            rpe_deltas: None,
        },
    )
    .unwrap();
    let k = r.kitti.expect("900 m holds 800 m segments");
    assert!(k.segments > 0 && k.t_err_pct < 1e-9 && k.r_err_deg_per_m < 1e-6);
    assert!(r.ate.none_rmse < 1e-12 && r.ate.se3_rmse < 1e-9 && r.ate.sim3_rmse < 1e-9);
    assert!((r.ate.sim3_scale - 1.0).abs() < 1e-9);
    for p in r.rpe.values() {
        assert!(p.trans_rmse < 1e-9 && p.rot_rmse_deg < 1e-5, "{p:?}");
    }
}

#[test]
fn umeyama_recovers_constant_scale_rotation_offset() {
    let gt = path(300);
    let transform = Isometry3::new(Vector3::new(4.0, -3.0, 2.0), Vector3::new(0.3, 0.2, -0.6));
    let scale = 0.37;
    // est = inverse similarity applied to gt, so aligning est onto gt needs (transform, scale).
    let inverse = transform.inverse();
    let poses = gt
        .poses
        .iter()
        .map(|p| {
            let mut q = inverse * p;
            q.translation.vector /= scale;
            q
        })
        .collect();
    let est = Trajectory::new(gt.timestamps.clone(), poses);
    let sim = umeyama(&est.positions(), &gt.positions(), true).unwrap();
    assert!((sim.scale - scale).abs() < 1e-9, "{}", sim.scale);
    assert!(sim.transform.rotation.angle_to(&transform.rotation) < 1e-9);
    assert!((sim.transform.translation.vector - transform.translation.vector).norm() < 1e-8);
    let sim3 = ate(&gt, &est, Alignment::Sim3).unwrap();
    assert!(sim3.stats.rmse < 1e-8 && (sim3.scale - scale).abs() < 1e-9);
    // A pure rigid offset is removed by SE3 alignment.
    let moved = gt.transformed(&transform, 1.0);
    assert!(ate(&gt, &moved, Alignment::Se3).unwrap().stats.rmse < 1e-8);
    assert!(ate(&gt, &moved, Alignment::None).unwrap().stats.rmse > 1.0);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    #[test]
    fn umeyama_recovers_random_sim3(
        axis_angle in prop::array::uniform3(-3.0f64..3.0),
        t in prop::array::uniform3(-50.0f64..50.0),
        log_scale in -2.0f64..2.0,
        pts in prop::collection::vec(prop::array::uniform3(-10.0f64..10.0), 6..40),
    ) {
        let rotation = UnitQuaternion::from_scaled_axis(Vector3::from(axis_angle));
        let scale = log_scale.exp();
        let source: Vec<Point3<f64>> = pts.iter().map(|p| Point3::from(*p)).collect();
        // Random points are almost surely non-degenerate; skip the rare near-collinear set.
        let centroid = source.iter().map(|p| p.coords).sum::<Vector3<f64>>() / source.len() as f64;
        let cov = source.iter().map(|p| (p.coords - centroid) * (p.coords - centroid).transpose()).sum::<nalgebra::Matrix3<f64>>();
        prop_assume!(cov.symmetric_eigenvalues().iter().filter(|&&e| e > 1e-3).count() >= 2);
        let target: Vec<Point3<f64>> = source.iter().map(|p| rotation * (p * scale) + Vector3::from(t)).collect();
        let sim = umeyama(&source, &target, true).unwrap();
        prop_assert!((sim.scale - scale).abs() < 1e-7 * scale.max(1.0));
        prop_assert!(sim.transform.rotation.angle_to(&rotation) < 1e-6);
        prop_assert!((sim.transform.translation.vector - Vector3::from(t)).norm() < 1e-6);
    }
}
