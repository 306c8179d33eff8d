//! Stereo matching of rectified pairs along rows, after ORB-SLAM3's
//! `Frame::ComputeStereoMatches`, with a ratio test along the row and guards
//! against periodic false matches.

mod params;
mod row_search;
mod sad;

pub use params::{PeriodicGuard, StereoParams};

use row_search::{RowBands, RowSearch};
use sad::{SadFailure, SadSearch};

use super::{check_kinds, check_rows, MatchError};
use crate::features::pyramid::{build_pyramid, ScaleTables};
use crate::features::{FrameFeatures, GrayImageView};

/// The rectified stereo images (level 0).
#[derive(Clone, Copy, Debug)]
pub struct StereoImages<'a> {
    /// Left image.
    pub left: GrayImageView<'a>,
    /// Right image.
    pub right: GrayImageView<'a>,
}

/// A left keypoint's match in the right image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StereoMatch {
    /// The right keypoint whose descriptor won.
    pub right_index: usize,
    /// Sub-pixel right column, level-0 pixels (ORB-SLAM3's `mvuRight`).
    pub right_u: f32,
    /// Depth in metres, `bf / disparity` (ORB-SLAM3's `mvDepth`).
    pub depth: f32,
    /// Descriptor distance of the winning right keypoint.
    pub distance: f32,
    /// SAD at the refined position (level-image grey levels).
    pub sad: f32,
}

/// How many left keypoints each stage rejected.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StereoRejections {
    /// No right keypoint on the row band within the disparity range.
    pub no_candidate: usize,
    /// Best descriptor distance above the threshold.
    pub distance: usize,
    /// Failed the ratio test along the row.
    pub ratio: usize,
    /// A near-best candidate one period from the best.
    pub periodic_descriptor: usize,
    /// The SAD patch would leave the image.
    pub border: usize,
    /// The SAD minimum at the end of the window.
    pub window_edge: usize,
    /// Parabola vertex more than a pixel away.
    pub sub_pixel: usize,
    /// A SAD dip as deep one period away.
    pub periodic_sad: usize,
    /// Refined disparity outside the range.
    pub disparity: usize,
    /// ORB-SLAM3's final SAD outlier rejection.
    pub sad_outlier: usize,
}

/// The result: one entry per left keypoint, and the rejection counts.
#[derive(Clone, Debug, PartialEq)]
pub struct StereoOutcome {
    /// `matches[i]` is left keypoint i's match.
    pub matches: Vec<Option<StereoMatch>>,
    /// Why the others have none.
    pub rejections: StereoRejections,
}

impl StereoOutcome {
    /// Number of left keypoints with a match.
    pub fn matched(&self) -> usize {
        self.matches.iter().filter(|m| m.is_some()).count()
    }
}

/// Matches left keypoints to the right image along rows. `tables` are the
/// extractor's scale tables (the keypoints' octaves index them). See the
/// module docs and [`StereoParams`].
pub fn match_stereo(
    left: &FrameFeatures,
    right: &FrameFeatures,
    images: StereoImages<'_>,
    tables: &ScaleTables,
    params: &StereoParams,
) -> Result<StereoOutcome, MatchError> {
    params.validate()?;
    check_rows(left)?;
    check_rows(right)?;
    check_kinds(left.descriptors.kind(), right.descriptors.kind())?;
    let (w, h) = (images.left.width(), images.left.height());
    if (w, h) != (images.right.width(), images.right.height()) {
        return Err(MatchError::ImageSizeMismatch {
            left_width: w,
            left_height: h,
            right_width: images.right.width(),
            right_height: images.right.height(),
        });
    }
    let levels = tables.n_levels();
    for kp in left.keypoints.iter().chain(&right.keypoints) {
        if kp.octave < 0 || kp.octave as usize >= levels {
            return Err(MatchError::OctaveOutOfRange {
                octave: kp.octave,
                levels,
            });
        }
    }
    let max_octave = left.keypoints.iter().map(|k| k.octave).max().unwrap_or(0);
    let (left_levels, right_levels) = if max_octave > 0 {
        (
            build_pyramid(images.left, tables)?,
            build_pyramid(images.right, tables)?,
        )
    } else {
        (Vec::new(), Vec::new())
    };

    let bands = RowBands::new(&right.keypoints, h, tables, params.row_sigma_factor);
    let search = RowSearch {
        left,
        right,
        bands: &bands,
        params,
    };
    let mut rejections = StereoRejections::default();
    let mut matches: Vec<Option<StereoMatch>> = vec![None; left.len()];
    let max_disparity = params.max_disparity();
    for (i, kp) in left.keypoints.iter().enumerate() {
        let octave = kp.octave as usize;
        let scale = tables.scale_factors[octave];
        let candidate = match search.best_on_row(i, scale) {
            Ok(c) => c,
            Err(reason) => {
                reason.count(&mut rejections);
                continue;
            }
        };
        let (left_image, right_image) = if octave == 0 {
            (images.left, images.right)
        } else {
            match (left_levels.get(octave), right_levels.get(octave)) {
                (Some(l), Some(r)) => (l.view(), r.view()),
                _ => {
                    rejections.border += 1;
                    continue;
                }
            }
        };
        let inv = tables.inv_scale_factors[octave];
        let sad = SadSearch {
            left: left_image,
            right: right_image,
            half: params.patch_half,
            radius: params.search_radius,
            periodic: params.periodic,
        };
        let right_u0 = right.keypoints[candidate.right_index].x;
        let fit = match sad.refine(
            (kp.x * inv).round() as i64,
            (kp.y * inv).round() as i64,
            (right_u0 * inv).round() as i64,
        ) {
            Ok(fit) => fit,
            Err(failure) => {
                match failure {
                    SadFailure::Border => rejections.border += 1,
                    SadFailure::WindowEdge => rejections.window_edge += 1,
                    SadFailure::SubPixelOutOfRange => rejections.sub_pixel += 1,
                    SadFailure::Periodic => rejections.periodic_sad += 1,
                }
                continue;
            }
        };
        let mut right_u = scale * fit.right_x;
        let mut disparity = kp.x - right_u;
        if !(disparity >= params.min_disparity && disparity < max_disparity) {
            rejections.disparity += 1;
            continue;
        }
        if disparity <= 0.0 {
            disparity = 0.01;
            right_u = kp.x - 0.01;
        }
        matches[i] = Some(StereoMatch {
            right_index: candidate.right_index,
            right_u,
            depth: params.bf / disparity,
            distance: candidate.distance,
            sad: fit.sad,
        });
    }
    rejections.sad_outlier = reject_sad_outliers(&mut matches, params.outlier_factor);
    Ok(StereoOutcome {
        matches,
        rejections,
    })
}

/// ORB-SLAM3's last step: SAD above factor x median SAD is an outlier.
/// (ORB-SLAM3 also drops SAD equal to the threshold, which removes every
/// match when the median SAD is 0; a strict comparison keeps them.)
/// Returns how many were removed.
fn reject_sad_outliers(matches: &mut [Option<StereoMatch>], factor: f32) -> usize {
    let mut sads: Vec<f32> = matches.iter().flatten().map(|m| m.sad).collect();
    if sads.is_empty() {
        return 0;
    }
    sads.sort_by(f32::total_cmp);
    let threshold = factor * sads[sads.len() / 2];
    let mut removed = 0;
    for m in matches.iter_mut() {
        if m.is_some_and(|m| m.sad > threshold) {
            *m = None;
            removed += 1;
        }
    }
    removed
}
