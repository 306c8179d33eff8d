//! Loop closing (ORB-SLAM3's `LoopClosing`) for a stereo map: detection with
//! the place-recognition database, the multi-stage geometric check, and the
//! correction (loop fusion and the essential graph).
//!
//! A layer beside local mapping: it reads and corrects a [`Map`](crate::map::Map),
//! uses [`place`](crate::place) for retrieval, and borrows tracking's
//! search-by-projection and pose-optimisation steps for the check (a loop
//! check is a relocalisation of a keyframe against older points). The
//! system layer ([`crate::system`]) decides when it runs.
//!
//! - [`LoopDetector`]: database, candidates, verification, confirmation;
//! - [`DatabaseRelocaliser`]: tracking's relocalisation candidates from
//!   the detector's (shared) database;
//! - [`verify_candidate`]: one candidate's check, stage by stage;
//! - [`LoopDrift`]: its last stage in the detector, whether the correction
//!   can be drift;
//! - [`MergeDetector`]: the same check against the older maps of the
//!   atlas (map merging; the merge itself is `Map::absorb` then
//!   [`correct_loop`]);
//! - [`correct_loop`]: the correction;
//! - [`build_essential_graph`] / [`optimise_essential_graph`]: the pose graph;
//! - [`snapshot_global_ba`] → [`solve_global_ba`] → [`apply_global_ba`]: the
//!   global bundle adjustment after a correction.

mod correct;
#[cfg(test)]
mod correct_tests;
mod detector;
mod drift;
mod essential_graph;
mod global_ba;
mod handover;
mod merge;
mod relocalisation;
mod side_scale;
mod stage_counts;
mod streak;
mod thresholds;
mod verify;

pub use correct::{correct_loop, LoopCorrection};
pub use detector::{
    AcceptedLoop, CandidateStep, DetectionOutcome, DetectionPlan, LoopDetector,
    SharedKeyframeDatabase,
};
pub use drift::{pose_difference, travel_between, LoopDrift, Travel};
pub use essential_graph::{
    build_essential_graph, optimise_essential_graph, EssentialGraph, EssentialGraphInput,
    EssentialGraphOutcome, GraphPose, MIN_ESSENTIAL_WEIGHT,
};
pub use global_ba::{
    apply_global_ba, snapshot_global_ba, solve_global_ba, GlobalBaSnapshot, GlobalBaSummary,
    SolvedGlobalBa, GLOBAL_BA_ITERATIONS,
};
pub use handover::{median_speed, Handover, HandoverGap};
pub use merge::{AcceptedMerge, MergeDetector, MergeOutcome};
pub use relocalisation::{DatabaseRelocaliser, RELOCALISATION_CANDIDATES};
pub use side_scale::{corrected_pose, scaled_correction, MIN_SCALE_PAIRS};
pub use stage_counts::{CandidateCheck, LoopStage, LoopStageCounts};
pub use thresholds::LoopThresholds;
pub use verify::{
    confirm_across, confirm_with, verify_across, verify_candidate, verify_with_counts,
    Confirmation, RejectedCandidate, Verification, VerifiedLoop,
};
