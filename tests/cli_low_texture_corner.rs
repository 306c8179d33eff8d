//! The bare-façade lap's start and first corner: `spslam synth --scene
//! loop --condition low-texture` (plaster walls, a few identical windows),
//! 640×480 as in the suite's `loop_lowtex_*_sp_anms`, its first 36 frames,
//! `spslam run --inline-mapping` with SuperPoint + ANMS (the defaults:
//! int8, one level), stereo and RGB-D.
//!
//! The shipped weights' descriptors seldom pass the ratio test on these
//! walls: between frames 20 and 21, where an 11.5° turn starts at once and
//! moves the image 78 px, 27 of 1000 keypoints pass ORB-SLAM3's 0.7 while
//! 150 of the 239 mutual nearest neighbours are right. The motion model,
//! the reference keyframe and the last frame then all failed and frames
//! 21–25 were lost in stereo (a second map from frame 26); in RGB-D the
//! frame after initialisation (no velocity yet) was lost the same way, and
//! frames 1–5. Tracking now tries the last frame's points by mutual
//! nearest neighbour without the ratio test as its last start, with PnP
//! RANSAC run long enough for a third of them to be right and only its
//! inliers kept (`src/tracking/motion.rs`, `track_last_frame_unratioed`).
//!
//! Measured (AMD EPYC with VNNI): every frame in one map, ATE (SE3)
//! 0.014 m stereo and 0.040 m RGB-D; the bound, 0.12 m, is three times the
//! larger, and a pose from a wrong RANSAC consensus is metres off.

mod common;

use common::cli::assert_lap_start_tracked_in_one_map;

/// Frames run: to just past the first corner (frames 21–28).
const FRAMES: usize = 36;
/// ATE (SE3) bound in metres over those frames.
const MAX_ATE_M: f64 = 0.12;

#[test]
fn the_bare_facades_first_corner_is_tracked_in_one_map_in_stereo() {
    if !common::model_available("the_bare_facades_first_corner_is_tracked_in_one_map_in_stereo") {
        return;
    }
    assert_lap_start_tracked_in_one_map("low-texture", FRAMES, "stereo", MAX_ATE_M);
}

#[test]
fn the_bare_facades_start_is_tracked_in_one_map_in_rgbd() {
    if !common::model_available("the_bare_facades_start_is_tracked_in_one_map_in_rgbd") {
        return;
    }
    assert_lap_start_tracked_in_one_map("low-texture", FRAMES, "rgbd", MAX_ATE_M);
}
