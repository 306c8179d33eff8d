//! SO(3) helpers on rotation vectors: hat, exp/log and the left Jacobian.

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

/// Angles below this use Taylor expansions (to θ⁴; the truncation error,
/// below θ⁶/5040 ≈ 2e-16, is under rounding).
pub(super) const SMALL_ANGLE: f64 = 1e-2;

/// The skew-symmetric matrix with `hat(w) v = w × v`.
pub fn hat(w: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -w.z, w.y, w.z, 0.0, -w.x, -w.y, w.x, 0.0)
}

/// The product `a·b` of two rotations, renormalised so rounding cannot
/// accumulate into a scale.
pub fn unit_product(a: &UnitQuaternion<f64>, b: &UnitQuaternion<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::new_normalize(a.quaternion() * b.quaternion())
}

/// Rotation from a rotation vector (axis × angle).
pub fn so3_exp(w: &Vector3<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::from_scaled_axis(*w)
}

/// Rotation vector of a rotation, with angle in [0, π].
pub fn so3_log(q: &UnitQuaternion<f64>) -> Vector3<f64> {
    // nalgebra's `scaled_axis` loses precision for tiny angles; use the
    // quaternion form directly, taking the short way round.
    let (w, v) = if q.w < 0.0 {
        (-q.w, -q.imag())
    } else {
        (q.w, q.imag())
    };
    let n = v.norm();
    if n < 1e-12 {
        return v * (2.0 / w);
    }
    let angle = 2.0 * n.atan2(w);
    v * (angle / n)
}

/// Left Jacobian of SO(3), `V(ω)` in `t = V(ω) υ` of SE(3)'s exp.
pub fn so3_left_jacobian(w: &Vector3<f64>) -> Matrix3<f64> {
    let theta = w.norm();
    let k = hat(w);
    let (a, b) = if theta < SMALL_ANGLE {
        (
            0.5 - theta * theta / 24.0,
            1.0 / 6.0 - theta * theta / 120.0,
        )
    } else {
        let t2 = theta * theta;
        (
            (1.0 - theta.cos()) / t2,
            (theta - theta.sin()) / (t2 * theta),
        )
    };
    Matrix3::identity() + k * a + k * k * b
}

/// Inverse of [`so3_left_jacobian`].
pub fn so3_left_jacobian_inverse(w: &Vector3<f64>) -> Matrix3<f64> {
    let theta = w.norm();
    let k = hat(w);
    let c = if theta < SMALL_ANGLE {
        let t2 = theta * theta;
        1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0
    } else {
        let half = 0.5 * theta;
        (1.0 - half / half.tan()) / (theta * theta)
    };
    Matrix3::identity() - k * 0.5 + k * k * c
}

/// The rotation matrix of a unit quaternion.
pub(super) fn rotation_matrix(q: &UnitQuaternion<f64>) -> Matrix3<f64> {
    Rotation3::from(*q).into_inner()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_inverts_exp_including_tiny_and_large_angles() {
        for w in [
            Vector3::new(1e-9, -2e-9, 3e-10),
            Vector3::new(0.3, -0.2, 0.1),
            Vector3::new(0.0, 3.1, 0.0),
        ] {
            let back = so3_log(&so3_exp(&w));
            assert!((back - w).norm() < 1e-12, "{w} -> {back}");
        }
    }

    #[test]
    fn left_jacobian_inverse_inverts_the_jacobian() {
        for w in [Vector3::new(1e-8, 0.0, 0.0), Vector3::new(0.7, -1.1, 0.4)] {
            let product = so3_left_jacobian(&w) * so3_left_jacobian_inverse(&w);
            assert!((product - Matrix3::identity()).norm() < 1e-12);
        }
    }
}
