//! The blurred lap's first corner in stereo: `spslam synth --scene loop
//! --blur 6` (half the frame interval's motion averaged into each image),
//! as in the suite's `loop_blur_stereo_sp_anms`, its first 32 frames,
//! `spslam run --inline-mapping` with SuperPoint + ANMS (the defaults),
//! without the second look (`--second-look-levels 0`), then with it.
//!
//! The corner turns 10–12° a frame from frame 21. Frames 21–24 cannot be
//! tracked against the map (their blurred keypoints miss the sharp map's
//! points) and were lost; a new map starts at frame 26. Consecutive
//! blurred frames match each other, so odometry measures each lost
//! frame's step from the frame before (`src/tracking/gap_odometry.rs`),
//! and a lost frame joined by steps to a frame with a pose gets its pose
//! along the chain (`src/system/odometry_chain.rs`). Measured (AMD EPYC,
//! AVX-512 VNNI, the whole lap): frames 21–24 posed by odometry, frame 25
//! localised after the loss; each chained step within 19 cm and 1.4° of
//! the true 1 m step (the suite's run: 216 → 228 of 232 frames tracked).

mod common;

use common::cli::{
    blurred_lap_start, frames_lost_and_maps, run_into, step_errors_to_truth,
    INLINE_SUPERPOINT_ANMS, INLINE_SUPERPOINT_ANMS_ONE_LOOK,
};
use common::temp_dir::TempDir;

/// Frames run: past the first corner and the new map it starts.
const FRAMES: usize = 32;
/// The corner's frames that tracking loses.
const CORNER: std::ops::RangeInclusive<usize> = 21..=24;
/// The largest error of a chained step against the true step: 0.19 m and
/// 1.34° measured, bounds at about 1.6×.
const MAX_STEP_ERROR_M: f64 = 0.3;
const MAX_STEP_ERROR_DEG: f64 = 2.2;

#[test]
fn the_blurred_corners_lost_frames_are_posed_by_odometry() {
    if !common::model_available("the_blurred_corners_lost_frames_are_posed_by_odometry") {
        return;
    }
    let dir = TempDir::new("blur-corner", "stereo");
    // Odometry alone: without the second look, which could track one of
    // the corner's frames on another CPU's int8 network.
    let (report, dataset) =
        blurred_lap_start(dir.path(), 0, FRAMES, &INLINE_SUPERPOINT_ANMS_ONE_LOOK);
    let (records, lost, maps) = frames_lost_and_maps(&report);
    assert_eq!(records.len(), FRAMES);
    let corner: Vec<String> = records[20..28]
        .iter()
        .map(|r| {
            format!(
                "{}: {} {} step {}",
                r["index"], r["method"], r["inliers"], r["gap_step_inliers"]
            )
        })
        .collect();
    eprintln!("lost {lost:?}; maps {maps:?}; the corner: {corner:?}");
    assert!(lost.is_empty(), "frames without a pose: {lost:?}");
    let by_odometry: Vec<usize> = CORNER
        .filter(|&i| records[i]["method"] == "Odometry")
        .collect();
    assert!(
        by_odometry.len() >= 3,
        "the corner's frames posed by odometry: {by_odometry:?}"
    );
    let all_by_odometry = records.iter().filter(|r| r["method"] == "Odometry").count() as u64;
    assert_eq!(
        report["summary"]["by_odometry"].as_u64(),
        Some(all_by_odometry),
        "the summary counts the frames posed by odometry"
    );
    // Each step into a frame posed by odometry, against the truth.
    for (k, metres, degrees) in step_errors_to_truth(dir.path(), &by_odometry) {
        assert!(
            metres <= MAX_STEP_ERROR_M && degrees <= MAX_STEP_ERROR_DEG,
            "frame {k}: step {metres:.3} m, {degrees:.2}° off the truth"
        );
    }
    // With the second look (the default, four levels,
    // `src/system/second_look.rs`) the corner's lost frames are looked at
    // again; here every look failed (measured: frames 21-24 and 27-31,
    // none tracked). A second look that fails leaves the run as it was:
    // every record and every pose is the one-look run's, up to the loss
    // in which a look first tracks a frame (none here; another CPU's int8
    // network may track one, and the frames of that loss are then posed
    // differently).
    assert_eq!(report["summary"]["second_looks"].as_u64(), Some(0));
    let looked_dir = dir.path().join("run_second_look");
    let looked = run_into(&looked_dir, &dataset, &INLINE_SUPERPOINT_ANMS);
    let looked_records = looked["frames"].as_array().expect("records");
    let first_tracked = looked_records
        .iter()
        .position(|r| r["second_look"] == "tracked")
        .unwrap_or(FRAMES);
    let mut same_until = first_tracked;
    while same_until > 0 && !looked_records[same_until - 1]["second_look"].is_null() {
        same_until -= 1;
    }
    let failed_looks = looked_records
        .iter()
        .filter(|r| r["second_look"] == "still_lost")
        .count();
    assert!(failed_looks >= 4, "failed second looks: {failed_looks}");
    let outcome = |r: &serde_json::Value| {
        (
            r["index"].clone(),
            r["state"].clone(),
            r["method"].clone(),
            r["inliers"].clone(),
            r["keyframe"].clone(),
            r["gap_step_inliers"].clone(),
        )
    };
    for (a, b) in records[..same_until].iter().zip(looked_records) {
        assert_eq!(
            outcome(a),
            outcome(b),
            "a failed second look changed a record"
        );
    }
    let rows = |d: &std::path::Path| -> Vec<String> {
        std::fs::read_to_string(d.join("trajectory_kitti.txt"))
            .expect("trajectory")
            .lines()
            .take(same_until)
            .map(String::from)
            .collect()
    };
    assert!(
        rows(&dir.path().join("run")) == rows(&looked_dir),
        "a failed second look changed the trajectory before frame {same_until}"
    );
}
