//! The repeated-texture lap's start in RGB-D: `spslam synth --scene loop
//! --condition repeated-texture` (every façade the same periodic grid of
//! windows), 640×480 as in the suite's `loop_repeated_rgbd_*`, its first
//! 52 frames, `spslam run --inline-mapping` with SuperPoint + ANMS (the
//! defaults: int8, one level).
//!
//! The camera drives 1 m a frame past façades whose pattern repeats every
//! 3 m. When the motion model's prediction kept fewer than half its matches
//! the tracker also tried the reference keyframe and kept whichever pose
//! had more local-map inliers; on these façades the reference keyframe's
//! descriptor matches and PnP RANSAC landed a period away, 3 m from the
//! motion model's pose, with more inliers (frame 41: 166 against 145), and
//! the constant velocity then carried the estimate backwards 2 m a frame
//! for ten frames (ATE SE3 8.03 m over these 52 frames; 16.4 m over the
//! whole lap in `EVALUATION.md`'s standard set). Another start now
//! replaces a motion-model pose with a relocalisation's 50 inliers only
//! within one step of it (`StepLimit` in `src/tracking/tracker.rs`).
//!
//! Measured (Intel Xeon with VNNI): every frame in one map, ATE (SE3)
//! 0.022 m; the bound, 0.1 m, is 4.5 times that, and a pose a period away
//! is metres off.

mod common;

use common::cli::assert_lap_start_tracked_in_one_map;

/// Frames run: past frames 41–50, where the estimate slipped a period.
const FRAMES: usize = 52;
/// ATE (SE3) bound in metres over those frames.
const MAX_ATE_M: f64 = 0.1;

#[test]
fn the_repeated_facades_are_not_tracked_a_period_away_in_rgbd() {
    if !common::model_available("the_repeated_facades_are_not_tracked_a_period_away_in_rgbd") {
        return;
    }
    assert_lap_start_tracked_in_one_map("repeated-texture", FRAMES, "rgbd", MAX_ATE_M);
}
