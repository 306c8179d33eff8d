//! The fundamental-matrix branch of ORB-SLAM3's `TwoViewReconstruction`: the
//! normalised 8-point algorithm with rank-2 enforcement (`ComputeF21`), the
//! epipolar-distance score (`CheckFundamental`), and the essential matrix
//! `E = Kᵀ·F·K` split into four motion hypotheses checked by triangulation
//! (`DecomposeE`, `ReconstructF`).

use nalgebra::{Matrix3, Point2, Vector3};

use super::homography::{k_matrix, CHI2_2DOF, MIN_TRIANGULATED_FRACTION};
use super::linalg::{matrix_from_row_major, null_vector9, svd3};
use super::triangulate::check_rt;
use super::{PinholeIntrinsics, Solution, TwoViewParams, TwoViewRejection};

/// χ² at 95 % for 1 degree of freedom: the per-image inlier threshold of
/// `CheckFundamental` (its score constant is [`CHI2_2DOF`], so F and H scores
/// are comparable).
const CHI2_1DOF: f64 = 3.841;

/// `ReconstructF` rejects when more than one hypothesis triangulates more than
/// this fraction of the best one's points.
const SIMILAR_RATIO: f64 = 0.7;

/// ORB-SLAM3's `ComputeF21`: the 8-point `x2ᵀ·F21·x1 = 0` from (normalised)
/// correspondences, the null vector read row-major, then the smallest singular
/// value zeroed (rank 2).
pub(crate) fn compute_f21(p1: &[Point2<f64>], p2: &[Point2<f64>]) -> Option<Matrix3<f64>> {
    let rows: Vec<[f64; 9]> = p1
        .iter()
        .zip(p2)
        .map(|(a, b)| {
            let (u1, v1, u2, v2) = (a.x, a.y, b.x, b.y);
            [u2 * u1, u2 * v1, u2, v2 * u1, v2 * v1, v2, u1, v1, 1.0]
        })
        .collect();
    let f_pre = matrix_from_row_major(&null_vector9(&rows)?);
    let (u, mut w, v) = svd3(&f_pre)?;
    w[2] = 0.0;
    Some(u * Matrix3::from_diagonal(&w) * v.transpose())
}

/// Squared distance from `p` to the line `l = (a, b, c)`; non-finite for a degenerate line.
fn line_distance2(l: &Vector3<f64>, p: &Point2<f64>) -> f64 {
    let num = l.x * p.x + l.y * p.y + l.z;
    num * num / (l.x * l.x + l.y * l.y)
}

/// ORB-SLAM3's `CheckFundamental`: pixel distance of each point to the epipolar
/// line of its match, in both images. A match is an inlier when `d²/σ² ≤ 3.841`
/// in both; each image where it is under the threshold adds `5.991 − d²/σ²` to
/// the score. Writes the inlier flags into `inliers` and returns the score.
pub(crate) fn check_fundamental(
    f21: &Matrix3<f64>,
    pixels1: &[Point2<f64>],
    pixels2: &[Point2<f64>],
    sigma: f64,
    inliers: &mut [bool],
) -> f64 {
    let inv_sigma2 = 1.0 / (sigma * sigma);
    let f21_t = f21.transpose();
    let mut score = 0.0;
    for ((p1, p2), inlier) in pixels1.iter().zip(pixels2).zip(inliers.iter_mut()) {
        let l2 = f21 * Vector3::new(p1.x, p1.y, 1.0);
        let l1 = f21_t * Vector3::new(p2.x, p2.y, 1.0);
        let mut is_in = true;
        for chi2 in [
            line_distance2(&l2, p2) * inv_sigma2,
            line_distance2(&l1, p1) * inv_sigma2,
        ] {
            // NaN fails the test too.
            if chi2 <= CHI2_1DOF {
                score += CHI2_2DOF - chi2;
            } else {
                is_in = false;
            }
        }
        *inlier = is_in;
    }
    score
}

/// ORB-SLAM3's `DecomposeE`: `t = ±u₃` (unit), `R1 = U·W·Vᵀ`, `R2 = U·Wᵀ·Vᵀ`,
/// each negated if its determinant is negative.
pub(crate) fn decompose_e(e: &Matrix3<f64>) -> Option<(Matrix3<f64>, Matrix3<f64>, Vector3<f64>)> {
    let (u, _, v) = svd3(e)?;
    let vt = v.transpose();
    let t: Vector3<f64> = u.column(2).into_owned();
    let t = t / t.norm();
    let w = Matrix3::new(0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0);
    let proper = |r: Matrix3<f64>| if r.determinant() < 0.0 { -r } else { r };
    let r1 = proper(u * w * vt);
    let r2 = proper(u * w.transpose() * vt);
    t.iter().all(|x| x.is_finite()).then_some((r1, r2, t))
}

/// ORB-SLAM3's `ReconstructF`: `E = Kᵀ·F21·K`, four hypotheses `(R1, t)`,
/// `(R2, t)`, `(R1, −t)`, `(R2, −t)` through [`check_rt`] (`th2 = 4σ²`); accept
/// the best when it triangulates at least `max(⌊0.9·N⌋, min_triangulated)` of
/// the `N` fundamental inliers, no other hypothesis triangulates more than
/// 70 % of its count, and its parallax exceeds `min_parallax_deg`.
pub(crate) fn reconstruct_f(
    camera: &PinholeIntrinsics,
    f21: &Matrix3<f64>,
    pixels1: &[Point2<f64>],
    pixels2: &[Point2<f64>],
    inliers: &[bool],
    params: &TwoViewParams,
) -> Result<Solution, TwoViewRejection> {
    let n_inliers = inliers.iter().filter(|&&b| b).count();
    let k = k_matrix(camera);
    let e21 = k.transpose() * f21 * k;
    let (r1, r2, t) = decompose_e(&e21).ok_or(TwoViewRejection::NoModel)?;
    let th2 = 4.0 * params.sigma * params.sigma;

    let mut solutions: Vec<Solution> = [(r1, t), (r2, t), (r1, -t), (r2, -t)]
        .into_iter()
        .map(|(rotation, translation)| Solution {
            check: check_rt(
                camera,
                &rotation,
                &translation,
                pixels1,
                pixels2,
                inliers,
                th2,
            ),
            rotation,
            translation,
            inliers: inliers.to_vec(),
        })
        .collect();
    let max_good = solutions.iter().map(|s| s.check.n_good).max().unwrap_or(0);
    let min_good =
        ((MIN_TRIANGULATED_FRACTION * n_inliers as f64) as usize).max(params.min_triangulated);
    if max_good < min_good || max_good == 0 {
        return Err(TwoViewRejection::TooFewTriangulated {
            triangulated: max_good,
            needed: min_good.max(1),
        });
    }
    // The first hypothesis with the highest count, as ORB-SLAM3's if/else chain.
    let best_idx = solutions
        .iter()
        .position(|s| s.check.n_good == max_good)
        .unwrap_or(0);
    let best = solutions.swap_remove(best_idx);
    // Written so that a NaN parallax or threshold rejects.
    let enough_parallax = best.check.parallax_deg > params.min_parallax_deg;
    if !enough_parallax {
        return Err(TwoViewRejection::LowParallax {
            parallax_deg: best.check.parallax_deg,
            needed_deg: params.min_parallax_deg,
        });
    }
    let similar = solutions
        .iter()
        .filter(|s| s.check.n_good as f64 > SIMILAR_RATIO * max_good as f64)
        .count();
    if similar > 0 {
        let second = solutions.iter().map(|s| s.check.n_good).max().unwrap_or(0);
        return Err(TwoViewRejection::Ambiguous {
            best: max_good,
            second,
        });
    }
    Ok(best)
}
