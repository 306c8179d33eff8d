//! ORB-SLAM3's `SearchByProjection` (frame against local map points): each
//! projected map point is compared with the frame's keypoints inside a
//! window scaled by its predicted octave.

use super::{check_rows, KeypointGrid, Match, MatchError};
use crate::features::{DescriptorRef, FrameFeatures};

/// A map point projected into the frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProjectedPoint<'a> {
    /// Projected column, level-0 pixels.
    pub u: f32,
    /// Projected row, level-0 pixels.
    pub v: f32,
    /// The octave predicted from the point's distance (`MapPoint::PredictScale`).
    pub predicted_octave: i32,
    /// The map point's representative descriptor.
    pub descriptor: DescriptorRef<'a>,
    /// Projected right-image column (`u − bf/z`), when the frame is stereo.
    pub u_right: Option<f32>,
}

/// Which of the frame's keypoints may be matched, and their stereo columns.
#[derive(Clone, Copy, Debug, Default)]
pub struct CandidateFilter<'a> {
    /// `taken[k]`: keypoint k already has a map point and is skipped
    /// (ORB-SLAM3 skips keypoints whose point has observations).
    pub taken: Option<&'a [bool]>,
    /// `right_u[k]`: keypoint k's right column; a candidate whose column is
    /// farther than the window from the point's projected right column is
    /// skipped (ORB-SLAM3's stereo check).
    pub right_u: Option<&'a [Option<f32>]>,
}

/// The best and second-best candidates with their octaves: ORB-SLAM3
/// applies the ratio test only when both come from the same octave.
#[derive(Clone, Copy, Debug)]
struct BestTwoLevels {
    best: Option<(usize, f32, i32)>,
    second: Option<(f32, i32)>,
}

impl BestTwoLevels {
    fn offer(&mut self, k: usize, d: f32, octave: i32) {
        match self.best {
            Some((_, bd, _)) if d >= bd => {
                if self.second.is_none_or(|(sd, _)| d < sd) {
                    self.second = Some((d, octave));
                }
            }
            Some((_, bd, bo)) => {
                self.second = Some((bd, bo));
                self.best = Some((k, d, octave));
            }
            None => self.best = Some((k, d, octave)),
        }
    }

    fn accept(&self, max_distance: f32, ratio: Option<f32>) -> Option<(usize, f32)> {
        let (k, d, octave) = self.best?;
        if d > max_distance {
            return None;
        }
        match (ratio, self.second) {
            (Some(r), Some((sd, so))) if so == octave && d > r * sd => None,
            _ => Some((k, d)),
        }
    }
}

/// The window and tests of a search by projection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProjectionParams {
    /// Window half-size at octave 0, in pixels; multiplied by
    /// `scale_factor^predicted_octave` (ORB-SLAM3's `th`, 1 to 15 depending on the call).
    pub radius: f32,
    /// Keypoints of octaves `predicted - below ..= predicted + above` are
    /// candidates (ORB-SLAM3: 1 and 0).
    pub octaves_below: i32,
    /// See [`octaves_below`](Self::octaves_below).
    pub octaves_above: i32,
    /// Ratio test on best / second best, applied when both are of the same
    /// octave as in ORB-SLAM3 (`None` disables).
    pub ratio: Option<f32>,
    /// Maximum descriptor distance (ORB-SLAM3: TH_HIGH).
    pub max_distance: f32,
}

/// Matches each projected point to the frame's best keypoint in its window.
/// A keypoint claimed by several points goes to the one with the smallest
/// distance. `scale_factors` is the extractor's table (ORB-SLAM3's
/// `mvScaleFactors`); points with an octave outside it are skipped. Returns
/// matches with `query` = point index, `train` = keypoint index, by query.
pub fn search_by_projection(
    points: &[ProjectedPoint<'_>],
    frame: &FrameFeatures,
    grid: &KeypointGrid,
    scale_factors: &[f32],
    params: ProjectionParams,
) -> Result<Vec<Match>, MatchError> {
    search_by_projection_filtered(
        points,
        frame,
        grid,
        scale_factors,
        params,
        CandidateFilter::default(),
    )
}

/// [`search_by_projection`] over the keypoints `filter` allows.
pub fn search_by_projection_filtered(
    points: &[ProjectedPoint<'_>],
    frame: &FrameFeatures,
    grid: &KeypointGrid,
    scale_factors: &[f32],
    params: ProjectionParams,
    filter: CandidateFilter<'_>,
) -> Result<Vec<Match>, MatchError> {
    check_rows(frame)?;
    if !(params.radius.is_finite() && params.radius > 0.0) {
        return Err(MatchError::InvalidParameter {
            name: "radius",
            value: params.radius,
            expected: "a positive number of pixels",
        });
    }
    let mut owner: Vec<Option<Match>> = vec![None; frame.len()];
    for (p, point) in points.iter().enumerate() {
        let Some(&scale) = usize::try_from(point.predicted_octave)
            .ok()
            .and_then(|o| scale_factors.get(o))
        else {
            continue;
        };
        let lo = point.predicted_octave - params.octaves_below;
        let hi = point.predicted_octave + params.octaves_above;
        let window = params.radius * scale;
        let mut best = BestTwoLevels {
            best: None,
            second: None,
        };
        for k in grid.features_in_area(point.u, point.v, window, Some((lo, hi))) {
            if filter
                .taken
                .and_then(|t| t.get(k))
                .copied()
                .unwrap_or(false)
            {
                continue;
            }
            if let (Some(ur), Some(Some(kr))) = (
                point.u_right,
                filter.right_u.and_then(|r| r.get(k)).copied(),
            ) {
                if (ur - kr).abs() > window {
                    continue;
                }
            }
            let Some(row) = frame.descriptors.row(k) else {
                continue;
            };
            let octave = frame.keypoints.get(k).map_or(0, |kp| kp.octave);
            let Some(d) = point.descriptor.distance(&row) else {
                return Err(MatchError::KindMismatch {
                    query: point.descriptor.kind(),
                    train: frame.descriptors.kind(),
                });
            };
            best.offer(k, d, octave);
        }
        if let Some((k, d)) = best.accept(params.max_distance, params.ratio) {
            if owner[k].is_none_or(|m| d < m.distance) {
                owner[k] = Some(Match {
                    query: p,
                    train: k,
                    distance: d,
                });
            }
        }
    }
    let mut matches: Vec<Match> = owner.into_iter().flatten().collect();
    matches.sort_by_key(|m| m.query);
    Ok(matches)
}
