//! Linear triangulation and ORB-SLAM3's `TwoViewReconstruction::CheckRT`:
//! triangulate every inlier under a motion hypothesis and keep the points
//! that are in front of both cameras and reproject within `th2`.

use nalgebra::{Matrix3, Matrix4, Point2, RowVector4, Vector3};

use super::linalg::null_vector4;
use super::PinholeIntrinsics;

/// `cos` of the ray angle below which a point counts as having parallax
/// (ORB-SLAM3's `0.99998`, about 0.36°).
pub(crate) const COS_PARALLAX_MAX: f64 = 0.99998;

/// ORB-SLAM3 reads the parallax off the sorted cosines at this index (see [`check_rt`]).
const PARALLAX_RANK: usize = 50;

/// The outcome of [`check_rt`] for one motion hypothesis.
#[derive(Debug, Clone)]
pub(crate) struct RtCheck {
    /// Points that passed the cheirality and reprojection checks (ORB-SLAM3's
    /// `nGood`; this includes points with too little parallax).
    pub n_good: usize,
    /// Per match: the point in camera-1 coordinates when it passed and has
    /// parallax (ORB-SLAM3's `vbGood`).
    pub points: Vec<Option<Vector3<f64>>>,
    /// The parallax of the hypothesis, degrees (0 when `n_good == 0`).
    pub parallax_deg: f64,
}

/// Pixel → normalised image coordinates `(x, y, 1)`.
pub(crate) fn unproject(camera: &PinholeIntrinsics, p: &Point2<f64>) -> Vector3<f64> {
    Vector3::new(
        (p.x - camera.cx) / camera.fx,
        (p.y - camera.cy) / camera.fy,
        1.0,
    )
}

/// Linear (DLT) triangulation, ORB-SLAM3's `GeometricTools::Triangulate`, for
/// `P1 = [I | 0]` and `P2 = [R | t]` on normalised image coordinates (ORB-SLAM3
/// uses `K·[I|0]`, `K·[R|t]` on pixels: the same rows scaled by `fx`, `fy`).
/// `None` for a point at infinity or a failed solve.
pub(crate) fn triangulate(
    x1: &Vector3<f64>,
    x2: &Vector3<f64>,
    r: &Matrix3<f64>,
    t: &Vector3<f64>,
) -> Option<Vector3<f64>> {
    let p1_row = |i: usize| {
        let mut row = RowVector4::zeros();
        row[i] = 1.0;
        row
    };
    let p2_row = |i: usize| RowVector4::new(r[(i, 0)], r[(i, 1)], r[(i, 2)], t[i]);
    let a = Matrix4::from_rows(&[
        p1_row(2) * x1.x - p1_row(0),
        p1_row(2) * x1.y - p1_row(1),
        p2_row(2) * x2.x - p2_row(0),
        p2_row(2) * x2.y - p2_row(1),
    ]);
    let h = null_vector4(&a)?;
    if h[3] == 0.0 {
        return None;
    }
    let p = h.xyz() / h[3];
    p.iter().all(|v| v.is_finite()).then_some(p)
}

/// Squared pixel distance between the projection of `p` (camera coordinates) and `uv`.
fn reprojection_error2(camera: &PinholeIntrinsics, p: &Vector3<f64>, uv: &Point2<f64>) -> f64 {
    let inv_z = 1.0 / p.z;
    let u = camera.fx * p.x * inv_z + camera.cx;
    let v = camera.fy * p.y * inv_z + camera.cy;
    (u - uv.x).powi(2) + (v - uv.y).powi(2)
}

/// ORB-SLAM3's `CheckRT`: triangulate every inlier match under `T_21 = [R | t]`
/// and count those in front of both cameras (only enforced when the ray angle
/// exceeds ≈0.36°, as "infinite" points can land behind) whose squared
/// reprojection error is at most `th2` pixels² in both images (ORB-SLAM3 calls
/// it with `th2 = 4σ²`). The parallax is read as ORB-SLAM3 does: the ray-angle
/// cosines of the good points sorted ascending, the one at index
/// `min(50, n − 1)`, i.e. the 51st-largest ray angle.
pub(crate) fn check_rt(
    camera: &PinholeIntrinsics,
    r: &Matrix3<f64>,
    t: &Vector3<f64>,
    pixels1: &[Point2<f64>],
    pixels2: &[Point2<f64>],
    inliers: &[bool],
    th2: f64,
) -> RtCheck {
    let n = pixels1.len().min(pixels2.len()).min(inliers.len());
    let mut points = vec![None; pixels1.len()];
    let mut cos_parallax = Vec::with_capacity(n);
    let o2 = -(r.transpose() * t);
    let mut n_good = 0;
    for i in 0..n {
        if !inliers[i] {
            continue;
        }
        let (uv1, uv2) = (&pixels1[i], &pixels2[i]);
        let Some(p1) = triangulate(&unproject(camera, uv1), &unproject(camera, uv2), r, t) else {
            continue;
        };
        let normal1 = p1;
        let normal2 = p1 - o2;
        let cos = normal1.dot(&normal2) / (normal1.norm() * normal2.norm());
        if !cos.is_finite() {
            continue;
        }
        let has_parallax = cos < COS_PARALLAX_MAX;
        if p1.z <= 0.0 && has_parallax {
            continue;
        }
        let p2 = r * p1 + t;
        if p2.z <= 0.0 && has_parallax {
            continue;
        }
        // NaN errors fail the test too.
        let reprojects = reprojection_error2(camera, &p1, uv1) <= th2
            && reprojection_error2(camera, &p2, uv2) <= th2;
        if !reprojects {
            continue;
        }
        cos_parallax.push(cos);
        n_good += 1;
        if has_parallax {
            points[i] = Some(p1);
        }
    }
    let parallax_deg = if cos_parallax.is_empty() {
        0.0
    } else {
        cos_parallax.sort_by(f64::total_cmp);
        let idx = PARALLAX_RANK.min(cos_parallax.len() - 1);
        cos_parallax[idx].clamp(-1.0, 1.0).acos().to_degrees()
    };
    RtCheck {
        n_good,
        points,
        parallax_deg,
    }
}
