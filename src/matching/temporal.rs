//! Frame-to-frame (or keyframe-to-frame) matching in a window around each
//! keypoint's previous (or predicted) position, with a ratio test: ORB-SLAM3's
//! `SearchForInitialization` without the octave-0 restriction.

use super::{check_kinds, check_rows, keep_consistent_rotation, BestTwo, KeypointGrid};
use super::{Match, MatchError};
use crate::features::FrameFeatures;

/// The window and tests of a temporal search.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TemporalParams {
    /// Window half-size in level-0 pixels (ORB-SLAM3's initialisation uses 100).
    pub window: f32,
    /// Candidates must lie within this many octaves of the query's.
    pub octave_tolerance: i32,
    /// Ratio test on best / second best (`None` disables); ORB-SLAM3 uses 0.9
    /// at initialisation, the paper's 0.7 is stricter.
    pub ratio: Option<f32>,
    /// Maximum descriptor distance (ORB-SLAM3: TH_LOW).
    pub max_distance: f32,
    /// Keep only matches whose angle change falls in the three most common
    /// of 30 histogram bins (ORB-SLAM3's `mbCheckOrientation`).
    pub check_orientation: bool,
}

/// Matches the keypoints of `previous` into `current` (indexed by
/// `current_grid`). `predicted`, when given, holds one predicted position per
/// previous keypoint (e.g. from a motion model); otherwise the previous
/// position is used. A current keypoint claimed twice goes to the smaller
/// distance. Returns matches with `query` in `previous`, `train` in
/// `current`, by query.
pub fn match_temporal(
    previous: &FrameFeatures,
    current: &FrameFeatures,
    current_grid: &KeypointGrid,
    predicted: Option<&[(f32, f32)]>,
    params: TemporalParams,
) -> Result<Vec<Match>, MatchError> {
    check_rows(previous)?;
    check_rows(current)?;
    check_kinds(previous.descriptors.kind(), current.descriptors.kind())?;
    if !(params.window.is_finite() && params.window > 0.0) {
        return Err(MatchError::InvalidParameter {
            name: "window",
            value: params.window,
            expected: "a positive number of pixels",
        });
    }
    if let Some(p) = predicted {
        if p.len() != previous.len() {
            return Err(MatchError::RowCount {
                keypoints: previous.len(),
                descriptors: p.len(),
            });
        }
    }
    let mut owner: Vec<Option<Match>> = vec![None; current.len()];
    for (i, kp) in previous.keypoints.iter().enumerate() {
        let (x, y) = predicted.map_or((kp.x, kp.y), |p| p[i]);
        let octaves = (
            kp.octave - params.octave_tolerance,
            kp.octave + params.octave_tolerance,
        );
        let mut best = BestTwo::default();
        for j in current_grid.features_in_area(x, y, params.window, Some(octaves)) {
            if let Some(d) = previous.descriptors.distance(i, &current.descriptors, j) {
                best.offer(j, d);
            }
        }
        if let Some((j, d)) = best.accept(params.max_distance, params.ratio) {
            if owner[j].is_none_or(|m| d < m.distance) {
                owner[j] = Some(Match {
                    query: i,
                    train: j,
                    distance: d,
                });
            }
        }
    }
    let mut matches: Vec<Match> = owner.into_iter().flatten().collect();
    matches.sort_by_key(|m| m.query);
    if params.check_orientation {
        keep_consistent_rotation(&mut matches, &previous.keypoints, &current.keypoints, 30);
    }
    Ok(matches)
}
