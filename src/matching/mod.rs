//! Descriptor matching for the SLAM front end, for both descriptor kinds
//! (SuperPoint's float rows by L2 distance, ORB's binary rows by Hamming):
//!
//! - [`match_brute_force`]: all pairs, Lowe's ratio test and a mutual check;
//! - [`KeypointGrid`] and [`search_by_projection`]: map points projected into a
//!   frame, searched within a radius scaled by the predicted octave;
//! - [`match_stereo`]: rectified left-right pairs along rows, descriptor ratio
//!   test, SAD patch refinement with a sub-pixel parabola, ORB-SLAM3's outlier
//!   rejection, and guards against periodic (one descriptor cell off) matches;
//! - [`match_temporal`]: frame-to-frame matching in a window, with a ratio test
//!   and an optional rotation-consistency check;
//! - [`DistanceThresholds`]: TH_LOW / TH_HIGH per descriptor kind, measured for
//!   SuperPoint (see `examples/descriptor_distances.rs`).

mod best_two;
mod brute_force;
pub mod dense;
mod error;
mod grid;
mod l2_rows;
mod projection;
mod rotation;
mod stereo;
mod temporal;

pub use crate::features::DistanceThresholds;
pub use best_two::BestTwo;
pub use brute_force::{
    match_brute_force, match_brute_force_spaced, Match, MatchParams, TrainLayout,
};
pub use error::MatchError;
pub use grid::{KeypointGrid, GRID_COLS, GRID_ROWS};
pub use projection::{
    search_by_projection, search_by_projection_filtered, CandidateFilter, ProjectedPoint,
    ProjectionParams,
};
pub use rotation::keep_consistent_rotation;
pub use stereo::{
    match_stereo, PeriodicGuard, StereoImages, StereoMatch, StereoOutcome, StereoParams,
    StereoRejections,
};
pub use temporal::{match_temporal, TemporalParams};

use crate::features::{DescriptorKind, FrameFeatures};

/// Checks one descriptor row per keypoint.
pub(crate) fn check_rows(features: &FrameFeatures) -> Result<(), MatchError> {
    if features.descriptors.len() != features.keypoints.len() {
        return Err(MatchError::RowCount {
            keypoints: features.keypoints.len(),
            descriptors: features.descriptors.len(),
        });
    }
    Ok(())
}

/// Checks that two descriptor kinds can be compared.
pub(crate) fn check_kinds(query: DescriptorKind, train: DescriptorKind) -> Result<(), MatchError> {
    if query != train {
        return Err(MatchError::KindMismatch { query, train });
    }
    Ok(())
}
