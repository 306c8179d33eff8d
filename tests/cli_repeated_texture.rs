//! The repeated-texture lap in RGB-D to just past its fourth corner: `spslam
//! synth --scene loop --condition repeated-texture` (every façade the same
//! periodic grid of windows), 640×480 as in the suite's
//! `loop_repeated_rgbd_*`, its first 208 frames, `spslam run
//! --inline-mapping` with SuperPoint + ANMS (the defaults: int8, one level).
//!
//! The camera drives 1 m a frame past façades whose pattern repeats every
//! 3 m, and twice the estimate slipped a period:
//! - frames 41–50: when the motion model's prediction kept fewer than half
//!   its matches the tracker also tried the reference keyframe and kept
//!   whichever pose had more local-map inliers; the reference keyframe's
//!   descriptor matches and PnP RANSAC landed a period away with more
//!   inliers (frame 41: 166 against 145), and the constant velocity then
//!   carried the estimate backwards for ten frames. Another start now
//!   replaces a motion-model pose only within one step of it or with twice
//!   its inliers (`StepLimit`, `src/tracking/step_limit.rs`).
//! - frame 204, where the fourth corner's turn starts at once (9.2°): the
//!   motion model kept 14 of its 165 matches, the reference keyframe and
//!   the last frame failed, and the search around the rotation the
//!   thumbnails showed (1.5°, 7.7° short) matched windows a period along:
//!   local-map tracking found 130 inliers 2.8 m sideways of the truth, the
//!   rotation right. That start changes only the rotation, so its pose may
//!   now lie at most a step (or a tenth of the scene's depth) from the
//!   constant velocity's prediction (`PredictionLimit`, same file); the
//!   last frame's points by mutual nearest neighbour then track frame 204
//!   (179 inliers).
//!
//! Measured (Intel Xeon with VNNI): every frame in one map; the largest
//! step error against the truth at frames 41–50 and 204–207 is 0.013 m
//! (3.0 m at frame 204 without the prediction limit, 2–3 m at frames 41–50
//! before the step limit); the bound, 1 m, is a third of a period. ATE
//! (SE3) 0.29 m over the 208 frames, no loop closed yet; bound 0.45 m.

mod common;

use common::cli::{
    assert_ate_at_most, assert_every_frame_in_one_map, run_lap_start, step_errors_to_truth,
};
use common::temp_dir::TempDir;

/// Frames run: past frame 204, the fourth corner's first frame.
const FRAMES: usize = 208;
/// ATE (SE3) bound in metres over those frames.
const MAX_ATE_M: f64 = 0.45;
/// Step error bound in metres where the estimate slipped a period (3 m).
const MAX_STEP_ERROR_M: f64 = 1.0;

#[test]
fn the_repeated_facades_are_not_tracked_a_period_away_in_rgbd() {
    if !common::model_available("the_repeated_facades_are_not_tracked_a_period_away_in_rgbd") {
        return;
    }
    let dir = TempDir::new("repeated-texture", "rgbd");
    let report = run_lap_start(dir.path(), "repeated-texture", FRAMES, "rgbd");
    let label = "repeated texture, RGB-D";
    assert_every_frame_in_one_map(&report, FRAMES, label);
    let slips: Vec<usize> = (41..=50).chain(204..=207).collect();
    for (frame, metres, _) in step_errors_to_truth(dir.path(), &slips) {
        assert!(
            metres <= MAX_STEP_ERROR_M,
            "{label}: frame {frame} stepped {metres:.2} m off the truth (> {MAX_STEP_ERROR_M} m): a period away"
        );
    }
    assert_ate_at_most(&report, MAX_ATE_M, label);
}
