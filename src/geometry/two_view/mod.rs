//! Monocular two-view reconstruction, after ORB-SLAM3 v1.0's
//! `TwoViewReconstruction` (src/TwoViewReconstruction.cc).
//!
//! [`reconstruct_two_views`] runs ORB-SLAM3's `Reconstruct`: a homography and a
//! fundamental matrix are fitted by RANSAC on the same 8-match samples
//! (`ransac.rs`: deterministic, seeded), each scored on all matches
//! (`CheckHomography`, `CheckFundamental`); the homography is chosen when
//! `SH / (SH + SF)` exceeds [`TwoViewParams::homography_ratio`] (or, not in
//! ORB-SLAM3, when it explains ≥ 90 % of the fundamental inliers). The chosen
//! model is then turned into motion hypotheses — eight from the Faugeras
//! decomposition of `H` (`homography.rs`), four from `E = Kᵀ·F·K`
//! (`fundamental.rs`) — and each is checked by triangulating the inliers
//! (`triangulate.rs`, ORB-SLAM3's `CheckRT`). The winner must triangulate most
//! inliers, clearly beat the other hypotheses and see enough parallax.
//!
//! Deviations from ORB-SLAM3: the plane-degeneracy rule above; a
//! least-squares refit of each RANSAC winner on its inliers (ORB-SLAM3 keeps
//! the minimal 8-point models and leaves accuracy to the initial bundle
//! adjustment; with σ = 0.5 px a minimal `F` is ~10° off in translation and
//! fails the triangulation checks); once a fundamental-matrix hypothesis
//! passes ORB-SLAM3's checks, its pose is polished by Levenberg–Marquardt on
//! the Sampson error (`refine.rs`) and the points re-triangulated; `f64`
//! throughout; triangulation on normalised image coordinates; matches with non-finite pixels are set
//! aside (never sampled, never triangulated) rather than poisoning the
//! normalisation; every degenerate solve ends in a [`TwoViewRejection`]
//! instead of a NaN.

mod fundamental;
mod homography;
mod linalg;
mod normalise;
mod ransac;
mod refine;
mod triangulate;

#[cfg(test)]
mod tests;

use nalgebra::{Matrix3, Point2, Vector3};

use crate::optim::Se3;

use self::linalg::nearest_rotation;
use self::normalise::normalise;
use self::ransac::{best_model, sample_sets, SAMPLE_SIZE};
use self::triangulate::RtCheck;

/// Pinhole intrinsics, pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PinholeIntrinsics {
    /// Focal length along `u`, pixels.
    pub fx: f64,
    /// Focal length along `v`, pixels.
    pub fy: f64,
    /// Principal point `u`, pixels.
    pub cx: f64,
    /// Principal point `v`, pixels.
    pub cy: f64,
}

impl PinholeIntrinsics {
    /// The pinhole matrix `K`.
    pub fn k(&self) -> Matrix3<f64> {
        Matrix3::new(self.fx, 0.0, self.cx, 0.0, self.fy, self.cy, 0.0, 0.0, 1.0)
    }

    /// `K⁻¹` in closed form.
    pub fn k_inverse(&self) -> Matrix3<f64> {
        Matrix3::new(
            1.0 / self.fx,
            0.0,
            -self.cx / self.fx,
            0.0,
            1.0 / self.fy,
            -self.cy / self.fy,
            0.0,
            0.0,
            1.0,
        )
    }
}

/// Which model explained the two views.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum TwoViewModel {
    /// A homography: a planar scene (or one far away); motion from the
    /// Faugeras decomposition (ORB-SLAM3's `ReconstructH`).
    Homography,
    /// A fundamental matrix: a general scene; motion from the essential
    /// matrix (ORB-SLAM3's `ReconstructF`).
    Fundamental,
}

/// Parameters of [`reconstruct_two_views`].
///
/// The defaults are ORB-SLAM3 v1.0's: `sigma` 1.0 and 200 iterations (the
/// `TwoViewReconstruction` constructor as `Tracking` builds it), `minParallax`
/// 1.0° and `minTriangulated` 50 (`TwoViewReconstruction::Reconstruct`), and
/// the homography chosen when `RH > 0.50` (`Reconstruct`: `if(RH>0.50)`; the
/// ORB-SLAM paper and ORB-SLAM2 used 0.45 / 0.40). The seed is fixed (0, as
/// ORB-SLAM3's `DUtils::Random::SeedRandOnce(0)`), though the generator is
/// this module's own SplitMix64, so the samples differ from ORB-SLAM3's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TwoViewParams {
    /// Pixel noise standard deviation: scales the χ² inlier tests and the
    /// reprojection threshold `4σ²` of the triangulation checks.
    pub sigma: f64,
    /// RANSAC iterations (the same sample sets serve both models).
    pub iterations: usize,
    /// Smallest accepted parallax, degrees (see [`TwoViewReconstruction::parallax_deg`]).
    pub min_parallax_deg: f64,
    /// Smallest number of triangulated points accepted (on top of 90 % of the
    /// chosen model's inliers).
    pub min_triangulated: usize,
    /// The homography is chosen when `SH / (SH + SF)` exceeds this (or when
    /// it explains ≥ 90 % of the fundamental inliers, see [`reconstruct_two_views`]).
    pub homography_ratio: f64,
    /// Seed of the RANSAC sampler.
    pub seed: u64,
}

impl Default for TwoViewParams {
    fn default() -> Self {
        Self {
            sigma: 1.0,
            iterations: 200,
            min_parallax_deg: 1.0,
            min_triangulated: 50,
            homography_ratio: 0.50,
            seed: 0,
        }
    }
}

/// The reconstruction.
#[derive(Debug, Clone, PartialEq)]
pub struct TwoViewReconstruction {
    /// T_21: maps camera-1 coordinates into camera 2; translation has unit norm (scale is arbitrary).
    pub pose_21: Se3,
    /// Per input match: the triangulated point in camera-1 coordinates, None when it failed a check.
    /// Points that passed every check but whose rays meet at less than ≈0.36°
    /// (`cos ≥ 0.99998`) are `None` too, as ORB-SLAM3's `vbTriangulated`.
    pub points: Vec<Option<Vector3<f64>>>,
    /// The model the motion came from.
    pub model: TwoViewModel,
    /// The score ratio SH / (SH + SF).
    pub homography_score_ratio: f64,
    /// Parallax of the accepted solution, degrees. ORB-SLAM3's `CheckRT`
    /// sorts the ray-angle cosines of the good points ascending and takes the
    /// one at index `min(50, n − 1)`: the 51st-largest ray angle.
    pub parallax_deg: f64,
    /// How many points were triangulated (the `Some` entries of [`Self::points`]).
    pub triangulated: usize,
}

/// Why two views could not be reconstructed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TwoViewRejection {
    /// Fewer usable (finite) matches than a minimal sample.
    #[error("too few matches: {matches} usable, {needed} needed")]
    TooFewMatches {
        /// Matches with finite pixels in both views.
        matches: usize,
        /// The minimal sample size (8).
        needed: usize,
    },
    /// RANSAC found nothing usable: degenerate input (identical or collinear
    /// points, invalid intrinsics or parameters) or a degenerate model.
    #[error("no homography or fundamental matrix could be fitted")]
    NoModel,
    /// The best motion hypothesis sees too little parallax.
    #[error("parallax {parallax_deg:.3}° below {needed_deg}°")]
    LowParallax {
        /// The parallax of the best hypothesis, degrees (0 for a homography
        /// that is a pure rotation).
        parallax_deg: f64,
        /// [`TwoViewParams::min_parallax_deg`].
        needed_deg: f64,
    },
    /// The best motion hypothesis triangulates too few points.
    #[error("{triangulated} points triangulated, {needed} needed")]
    TooFewTriangulated {
        /// Points that passed `CheckRT` for the best hypothesis (ORB-SLAM3's
        /// `nGood`, low-parallax points included).
        triangulated: usize,
        /// The count the rule asks for.
        needed: usize,
    },
    /// No clear winner among the motion hypotheses: in `ReconstructF` another
    /// hypothesis triangulates more than 70 % of the best one's points; in
    /// `ReconstructH` the second best has at least 75 % of them.
    #[error("ambiguous motion: best hypothesis {best} points, next {second}")]
    Ambiguous {
        /// Points of the best hypothesis.
        best: usize,
        /// Points of the runner-up.
        second: usize,
    },
}

/// An accepted motion hypothesis with its triangulation.
#[derive(Debug, Clone)]
pub(crate) struct Solution {
    /// `R_21`.
    pub rotation: Matrix3<f64>,
    /// `t_21`, unit norm.
    pub translation: Vector3<f64>,
    /// Its `CheckRT` outcome, indexed by usable match.
    pub check: RtCheck,
    /// The inliers of the model it came from (what `CheckRT` triangulated).
    pub inliers: Vec<bool>,
}

/// A fundamental matrix counts as degenerate (planar scene) when at least this
/// fraction of its inliers are homography inliers too.
const PLANAR_INLIER_FRACTION: f64 = 0.9;

/// The plane-degeneracy test that overrides the score ratio (not in ORB-SLAM3):
/// on a plane every member of a family of fundamental matrices fits the
/// matches, and with ORB-SLAM3's scores a point-to-line residual (1 degree of
/// freedom, `5.991 − χ²` with a smaller `χ²`) outscores the point-to-point
/// transfer of the homography (2 degrees of freedom): with Gaussian pixel
/// noise a planar scene gives `SH / (SH + SF)` ≈ 0.48, under ORB-SLAM3 v1.0's
/// 0.50, and `ReconstructF` then fails on the degenerate `F`. So the homography
/// is also chosen when it explains ≥ 90 % of the fundamental inliers.
fn plane_explains(h_inliers: &[bool], f_inliers: &[bool]) -> bool {
    let f_count = f_inliers.iter().filter(|&&b| b).count();
    let both = h_inliers
        .iter()
        .zip(f_inliers)
        .filter(|(&a, &b)| a && b)
        .count();
    f_count >= SAMPLE_SIZE && both as f64 >= PLANAR_INLIER_FRACTION * f_count as f64
}

/// ORB-SLAM3's `TwoViewReconstruction::Reconstruct`: homography and fundamental
/// matrix by RANSAC on the same 8-point samples, scored with ORB-SLAM3's
/// `CheckHomography` / `CheckFundamental` (χ² 5.991 per side for H, 3.841 for F
/// with the 5.991 score constant), choose H when `SH/(SH+SF) > homography_ratio`,
/// then `ReconstructH` or `ReconstructF` with the parallax and triangulation
/// checks.
///
/// Three additions to ORB-SLAM3, each documented where it lives: each RANSAC
/// winner is refitted by least squares on its inliers while that raises its
/// score; the homography is also chosen when it explains at least 90 % of
/// the fundamental matrix's inliers (a planar scene, where ORB-SLAM3's score
/// ratio falls just under 0.50 and its `ReconstructF` fails); a pose accepted
/// from `F` is polished on the Sampson error before the final triangulation.
///
/// `matches` are `(pixel in view 1, pixel in view 2)`, undistorted level-0
/// pixels. Matches with a non-finite coordinate are ignored (their point is
/// `None`). Deterministic: the same input gives the same output. Never panics;
/// every failure is a [`TwoViewRejection`].
pub fn reconstruct_two_views(
    camera: &PinholeIntrinsics,
    matches: &[(Point2<f64>, Point2<f64>)],
    params: &TwoViewParams,
) -> Result<TwoViewReconstruction, TwoViewRejection> {
    let usable: Vec<usize> = matches
        .iter()
        .enumerate()
        .filter(|(_, (a, b))| a.iter().chain(b.iter()).all(|v| v.is_finite()))
        .map(|(i, _)| i)
        .collect();
    if usable.len() < SAMPLE_SIZE {
        return Err(TwoViewRejection::TooFewMatches {
            matches: usable.len(),
            needed: SAMPLE_SIZE,
        });
    }
    let camera_ok = [camera.fx, camera.fy, camera.cx, camera.cy]
        .iter()
        .all(|v| v.is_finite())
        && camera.fx != 0.0
        && camera.fy != 0.0;
    let sigma_ok = params.sigma.is_finite() && params.sigma > 0.0;
    if !camera_ok || !sigma_ok {
        return Err(TwoViewRejection::NoModel);
    }
    let pixels1: Vec<Point2<f64>> = usable.iter().map(|&i| matches[i].0).collect();
    let pixels2: Vec<Point2<f64>> = usable.iter().map(|&i| matches[i].1).collect();
    let norm1 = normalise(&pixels1).ok_or(TwoViewRejection::NoModel)?;
    let norm2 = normalise(&pixels2).ok_or(TwoViewRejection::NoModel)?;
    let t1 = norm1.transform;
    let t2_inv = norm2
        .transform
        .try_inverse()
        .ok_or(TwoViewRejection::NoModel)?;
    let t2_t = norm2.transform.transpose();

    let sets = sample_sets(usable.len(), params.iterations, params.seed);
    // FindHomography.
    let h = best_model(
        &sets,
        &norm1.points,
        &norm2.points,
        |a, b| homography::compute_h21(a, b).map(|hn| t2_inv * hn * t1),
        |h21, inliers| match h21.try_inverse() {
            Some(h12) => {
                homography::check_homography(h21, &h12, &pixels1, &pixels2, params.sigma, inliers)
            }
            None => {
                inliers.fill(false);
                0.0
            }
        },
    );
    // FindFundamental.
    let f = best_model(
        &sets,
        &norm1.points,
        &norm2.points,
        |a, b| fundamental::compute_f21(a, b).map(|fn_| t2_t * fn_ * t1),
        |f21, inliers| {
            fundamental::check_fundamental(f21, &pixels1, &pixels2, params.sigma, inliers)
        },
    );

    let sh = h.as_ref().map_or(0.0, |r| r.score);
    let sf = f.as_ref().map_or(0.0, |r| r.score);
    // Written so that a NaN score counts as none.
    let scored = sh + sf > 0.0;
    if !scored {
        return Err(TwoViewRejection::NoModel);
    }
    let ratio = sh / (sh + sf);
    let choose_h = ratio > params.homography_ratio
        || matches!((&h, &f), (Some(h), Some(f)) if plane_explains(&h.inliers, &f.inliers));
    let (model, solution) = match (choose_h, h, f) {
        (true, Some(h), _) => (
            TwoViewModel::Homography,
            homography::reconstruct_h(camera, &h.model, &pixels1, &pixels2, &h.inliers, params)?,
        ),
        (_, _, Some(f)) => (
            TwoViewModel::Fundamental,
            fundamental::reconstruct_f(camera, &f.model, &pixels1, &pixels2, &f.inliers, params)?,
        ),
        _ => return Err(TwoViewRejection::NoModel),
    };

    // On a plane the epipolar (Sampson) cost is nearly flat along the
    // fundamental-matrix family, so only the F branch is polished.
    let solution = match model {
        TwoViewModel::Fundamental => refine::polish(camera, solution, &pixels1, &pixels2, params),
        TwoViewModel::Homography => solution,
    };
    let rotation = nearest_rotation(&solution.rotation).ok_or(TwoViewRejection::NoModel)?;
    let t_norm = solution.translation.norm();
    if !(t_norm.is_finite() && t_norm > 0.0) {
        return Err(TwoViewRejection::NoModel);
    }
    let mut points = vec![None; matches.len()];
    for (k, &i) in usable.iter().enumerate() {
        points[i] = solution.check.points.get(k).copied().flatten();
    }
    let triangulated = points.iter().filter(|p| p.is_some()).count();
    Ok(TwoViewReconstruction {
        pose_21: Se3::new(rotation, solution.translation / t_norm),
        points,
        model,
        homography_score_ratio: ratio,
        parallax_deg: solution.check.parallax_deg,
        triangulated,
    })
}
