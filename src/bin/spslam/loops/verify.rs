//! Geometric verification of a place-recognition candidate without
//! calibration: mutual-nearest-neighbour SuperPoint matches with Lowe's
//! ratio test, then a fundamental matrix by RANSAC (OpenCV's
//! `findFundamentalMat`); the candidate's evidence is the inlier count.

use anyhow::{Context, Result};
use opencv::core::{Mat, Point2f, Vector};
use opencv::prelude::*;
use spslam::features::DescriptorSet;
use spslam::matching::{match_brute_force, MatchParams};

/// Lowe's ratio for the putative matches: looser than the paper's 0.7,
/// since a revisit seen from a different pose has fewer, less distinctive
/// correspondences, and RANSAC removes the outliers.
pub const MATCH_RATIO: f32 = 0.8;
/// RANSAC's threshold: distance to the epipolar line, in pixels.
pub const RANSAC_THRESHOLD_PX: f64 = 1.0;
/// RANSAC's confidence.
pub const RANSAC_CONFIDENCE: f64 = 0.999;
/// RANSAC's iteration cap.
pub const RANSAC_MAX_ITERS: i32 = 2000;
/// Below this many putative matches no fundamental matrix is estimated
/// (the 8-point solver's minimum).
const MIN_MATCHES_FOR_F: usize = 8;

/// One image's keypoints and descriptors.
pub struct ImageFeatures {
    /// Keypoint positions (pixels).
    pub points: Vec<(f32, f32)>,
    /// Their descriptors, one row per keypoint.
    pub descriptors: DescriptorSet,
}

/// What verification found between two images.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Verification {
    /// Putative matches (mutual nearest neighbours passing the ratio test).
    pub matches: usize,
    /// Of those, the fundamental matrix's RANSAC inliers (0 below 8 matches).
    pub inliers: usize,
    /// The inlier matches: (keypoint in the first image, keypoint in the second).
    pub inlier_pairs: Vec<(usize, usize)>,
}

/// Matches `a` with `b` and counts the inliers of a RANSAC fundamental matrix.
pub fn verify(a: &ImageFeatures, b: &ImageFeatures) -> Result<Verification> {
    let params = MatchParams {
        ratio: Some(MATCH_RATIO),
        max_distance: f32::INFINITY,
        mutual: true,
    };
    let matches = match_brute_force(&a.descriptors, &b.descriptors, params)
        .context("cannot match the descriptors")?;
    if matches.len() < MIN_MATCHES_FOR_F {
        return Ok(Verification {
            matches: matches.len(),
            inliers: 0,
            inlier_pairs: Vec::new(),
        });
    }
    let mut pa = Vector::<Point2f>::with_capacity(matches.len());
    let mut pb = Vector::<Point2f>::with_capacity(matches.len());
    for m in &matches {
        let (xa, ya) = a.points[m.query];
        let (xb, yb) = b.points[m.train];
        pa.push(Point2f::new(xa, ya));
        pb.push(Point2f::new(xb, yb));
    }
    let mut mask = Mat::default();
    let f = opencv::calib3d::find_fundamental_mat(
        &pa,
        &pb,
        opencv::calib3d::FM_RANSAC,
        RANSAC_THRESHOLD_PX,
        RANSAC_CONFIDENCE,
        RANSAC_MAX_ITERS,
        &mut mask,
    )
    .context("fundamental-matrix RANSAC failed")?;
    let mut inlier_pairs = Vec::new();
    if !f.empty() && mask.total() == matches.len() {
        let flags = mask.data_bytes()?;
        inlier_pairs = matches
            .iter()
            .zip(flags)
            .filter(|(_, &flag)| flag != 0)
            .map(|(m, _)| (m.query, m.train))
            .collect();
    }
    Ok(Verification {
        matches: matches.len(),
        inliers: inlier_pairs.len(),
        inlier_pairs,
    })
}
