//! The homography branch of ORB-SLAM3's `TwoViewReconstruction`: the
//! normalised DLT (`ComputeH21`), the symmetric-transfer score
//! (`CheckHomography`) and the Faugeras decomposition into eight motion
//! hypotheses checked by triangulation (`ReconstructH`).

use nalgebra::{Matrix3, Point2, Vector3};

use super::linalg::{matrix_from_row_major, null_vector9, svd3};
use super::triangulate::check_rt;
use super::{PinholeIntrinsics, Solution, TwoViewParams, TwoViewRejection};

/// χ² at 95 % for 2 degrees of freedom: the per-image inlier threshold and
/// score constant of `CheckHomography`.
pub(crate) const CHI2_2DOF: f64 = 5.991;

/// ORB-SLAM3's ratio below which two singular values of `K⁻¹·H·K` count as equal.
const SINGULAR_RATIO_MIN: f64 = 1.00001;

/// `ReconstructH` rejects when the second-best hypothesis triangulates at least
/// this fraction of the best one's points.
const SECOND_BEST_RATIO: f64 = 0.75;

/// Both `ReconstructH` and `ReconstructF` want at least this fraction of the
/// model's inliers triangulated.
pub(crate) const MIN_TRIANGULATED_FRACTION: f64 = 0.9;

/// ORB-SLAM3's `ComputeH21`: the DLT homography `x2 ~ H21·x1` from (normalised)
/// correspondences, two rows per match, the null vector read row-major.
pub(crate) fn compute_h21(p1: &[Point2<f64>], p2: &[Point2<f64>]) -> Option<Matrix3<f64>> {
    let rows: Vec<[f64; 9]> = p1
        .iter()
        .zip(p2)
        .flat_map(|(a, b)| {
            let (u1, v1, u2, v2) = (a.x, a.y, b.x, b.y);
            [
                [0.0, 0.0, 0.0, -u1, -v1, -1.0, v2 * u1, v2 * v1, v2],
                [u1, v1, 1.0, 0.0, 0.0, 0.0, -u2 * u1, -u2 * v1, -u2],
            ]
        })
        .collect();
    null_vector9(&rows).map(|x| matrix_from_row_major(&x))
}

/// `H·p` dehomogenised; non-finite when `p` maps to infinity.
fn transfer(h: &Matrix3<f64>, p: &Point2<f64>) -> Point2<f64> {
    let x = h * Vector3::new(p.x, p.y, 1.0);
    Point2::new(x.x / x.z, x.y / x.z)
}

/// ORB-SLAM3's `CheckHomography`: symmetric transfer error in pixels. A match
/// is an inlier when `d²/σ² ≤ 5.991` in both images; each image where it is
/// under the threshold adds `5.991 − d²/σ²` to the score. Writes the inlier
/// flags into `inliers` and returns the score.
pub(crate) fn check_homography(
    h21: &Matrix3<f64>,
    h12: &Matrix3<f64>,
    pixels1: &[Point2<f64>],
    pixels2: &[Point2<f64>],
    sigma: f64,
    inliers: &mut [bool],
) -> f64 {
    let inv_sigma2 = 1.0 / (sigma * sigma);
    let mut score = 0.0;
    for ((p1, p2), inlier) in pixels1.iter().zip(pixels2).zip(inliers.iter_mut()) {
        let mut is_in = true;
        for chi2 in [
            (transfer(h12, p2) - p1).norm_squared() * inv_sigma2,
            (transfer(h21, p1) - p2).norm_squared() * inv_sigma2,
        ] {
            // NaN fails the test too.
            if chi2 <= CHI2_2DOF {
                score += CHI2_2DOF - chi2;
            } else {
                is_in = false;
            }
        }
        *inlier = is_in;
    }
    score
}

/// The pinhole matrix `K`.
pub(crate) fn k_matrix(c: &PinholeIntrinsics) -> Matrix3<f64> {
    c.k()
}

/// `K⁻¹` in closed form.
pub(crate) fn k_inverse(c: &PinholeIntrinsics) -> Matrix3<f64> {
    c.k_inverse()
}

/// A motion hypothesis `(R_21, t_21)`.
pub(crate) type Motion = (Matrix3<f64>, Vector3<f64>);

/// Why the Faugeras decomposition could not run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum DecompositionFailure {
    /// All three singular values of `K⁻¹·H·K` equal: a pure rotation.
    Rotation,
    /// Two singular values equal, or the SVD failed.
    Degenerate,
}

/// The eight `(R, t)` hypotheses of Faugeras and Lustman (1988), exactly as
/// ORB-SLAM3's `ReconstructH` builds them (`t` normalised to unit length):
/// four for `d' = d2`, four for `d' = −d2`.
pub(crate) fn decompose_homography(
    h21: &Matrix3<f64>,
    camera: &PinholeIntrinsics,
) -> Result<Vec<Motion>, DecompositionFailure> {
    let a = k_inverse(camera) * h21 * k_matrix(camera);
    let (u, w, v) = svd3(&a).ok_or(DecompositionFailure::Degenerate)?;
    let vt = v.transpose();
    let s = u.determinant() * vt.determinant();
    let (d1, d2, d3) = (w[0], w[1], w[2]);
    // Written so that NaN ratios (d2 = d3 = 0) count as equal values.
    let distinct = d1 / d2 >= SINGULAR_RATIO_MIN && d2 / d3 >= SINGULAR_RATIO_MIN;
    if !distinct {
        return Err(if d1 / d3 < SINGULAR_RATIO_MIN {
            DecompositionFailure::Rotation
        } else {
            DecompositionFailure::Degenerate
        });
    }
    let (d1s, d2s, d3s) = (d1 * d1, d2 * d2, d3 * d3);
    // n' = [x1 0 x3]: e1 = e3 = 1, e1 = 1 e3 = −1, e1 = −1 e3 = 1, e1 = e3 = −1.
    let aux1 = ((d1s - d2s) / (d1s - d3s)).sqrt();
    let aux3 = ((d2s - d3s) / (d1s - d3s)).sqrt();
    let x1 = [aux1, aux1, -aux1, -aux1];
    let x3 = [aux3, -aux3, aux3, -aux3];

    let mut hypotheses = Vec::with_capacity(8);
    let mut push = |rp: Matrix3<f64>, tp: Vector3<f64>| {
        let r = u * rp * vt * s;
        let t = u * tp;
        let norm = t.norm();
        hypotheses.push((r, t / norm));
    };

    // Case d' = d2.
    let aux_stheta = ((d1s - d2s) * (d2s - d3s)).sqrt() / ((d1 + d3) * d2);
    let ctheta = (d2s + d1 * d3) / ((d1 + d3) * d2);
    let stheta = [aux_stheta, -aux_stheta, -aux_stheta, aux_stheta];
    for i in 0..4 {
        #[rustfmt::skip]
        let rp = Matrix3::new(
            ctheta, 0.0, -stheta[i],
            0.0, 1.0, 0.0,
            stheta[i], 0.0, ctheta,
        );
        let tp = Vector3::new(x1[i], 0.0, -x3[i]) * (d1 - d3);
        push(rp, tp);
    }

    // Case d' = −d2.
    let aux_sphi = ((d1s - d2s) * (d2s - d3s)).sqrt() / ((d1 - d3) * d2);
    let cphi = (d1 * d3 - d2s) / ((d1 - d3) * d2);
    let sphi = [aux_sphi, -aux_sphi, -aux_sphi, aux_sphi];
    for i in 0..4 {
        #[rustfmt::skip]
        let rp = Matrix3::new(
            cphi, 0.0, sphi[i],
            0.0, -1.0, 0.0,
            sphi[i], 0.0, -cphi,
        );
        let tp = Vector3::new(x1[i], 0.0, x3[i]) * (d1 + d3);
        push(rp, tp);
    }

    if hypotheses
        .iter()
        .any(|(r, t)| !(r.iter().all(|v| v.is_finite()) && t.iter().all(|v| v.is_finite())))
    {
        return Err(DecompositionFailure::Degenerate);
    }
    Ok(hypotheses)
}

/// ORB-SLAM3's `ReconstructH`: decompose `H21`, run [`check_rt`] (with
/// `th2 = 4σ²`) on all eight hypotheses and accept the best when it triangulates
/// more than `min_triangulated` points and more than 90 % of the homography
/// inliers, has parallax ≥ `min_parallax_deg`, and the second best triangulates
/// fewer than 75 % of its points.
pub(crate) fn reconstruct_h(
    camera: &PinholeIntrinsics,
    h21: &Matrix3<f64>,
    pixels1: &[Point2<f64>],
    pixels2: &[Point2<f64>],
    inliers: &[bool],
    params: &TwoViewParams,
) -> Result<Solution, TwoViewRejection> {
    let n_inliers = inliers.iter().filter(|&&b| b).count();
    let hypotheses = decompose_homography(h21, camera).map_err(|e| match e {
        DecompositionFailure::Rotation => TwoViewRejection::LowParallax {
            parallax_deg: 0.0,
            needed_deg: params.min_parallax_deg,
        },
        DecompositionFailure::Degenerate => TwoViewRejection::NoModel,
    })?;
    let th2 = 4.0 * params.sigma * params.sigma;

    let mut best: Option<Solution> = None;
    let mut second_good = 0usize;
    for (r, t) in hypotheses {
        let check = check_rt(camera, &r, &t, pixels1, pixels2, inliers, th2);
        let best_good = best.as_ref().map_or(0, |b| b.check.n_good);
        if check.n_good > best_good {
            second_good = best_good;
            best = Some(Solution {
                rotation: r,
                translation: t,
                check,
                inliers: inliers.to_vec(),
            });
        } else if check.n_good > second_good {
            second_good = check.n_good;
        }
    }
    let Some(best) = best else {
        return Err(TwoViewRejection::TooFewTriangulated {
            triangulated: 0,
            needed: needed_strictly_above(params.min_triangulated, n_inliers),
        });
    };
    let good = best.check.n_good;
    if good <= params.min_triangulated
        || (good as f64) <= MIN_TRIANGULATED_FRACTION * n_inliers as f64
    {
        return Err(TwoViewRejection::TooFewTriangulated {
            triangulated: good,
            needed: needed_strictly_above(params.min_triangulated, n_inliers),
        });
    }
    // Written so that a NaN parallax or threshold rejects.
    let enough_parallax = best.check.parallax_deg >= params.min_parallax_deg;
    if !enough_parallax {
        return Err(TwoViewRejection::LowParallax {
            parallax_deg: best.check.parallax_deg,
            needed_deg: params.min_parallax_deg,
        });
    }
    let clear_winner = (second_good as f64) < SECOND_BEST_RATIO * good as f64;
    if !clear_winner {
        return Err(TwoViewRejection::Ambiguous {
            best: good,
            second: second_good,
        });
    }
    Ok(best)
}

/// The smallest count `c` with `c > min_triangulated` and `c > 0.9·n_inliers`.
fn needed_strictly_above(min_triangulated: usize, n_inliers: usize) -> usize {
    let by_fraction = (MIN_TRIANGULATED_FRACTION * n_inliers as f64).floor() as usize + 1;
    (min_triangulated + 1).max(by_fraction)
}
