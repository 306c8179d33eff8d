//! The second look at a lost frame (`src/system/second_look.rs`) on the
//! blurred lap's first corner, third rendering: `spslam synth --scene loop
//! --blur 6 --seed 2`, as in the suite's `loop_blur_s2_stereo_sp_anms`, its
//! first 32 frames, `spslam run --inline-mapping` with SuperPoint + ANMS
//! (the defaults: one pyramid level, a second look on four).
//!
//! The corner turns 10–12° a frame from frame 21. On one level frame 21's
//! blurred keypoints miss the map's points and its first try is lost;
//! extracted again on four levels it is tracked against the map. Measured
//! (AMD EPYC, AVX-512 VNNI): frame 21 tracked on the second look with 37
//! inliers, 0.038 m and 0.81° from the true step (the whole lap: 229 → 232
//! of 232 frames tracked). The test asks it of one of the corner's frames
//! 21–24, since another CPU's int8 network may lose a different one.

mod common;

use common::cli::{
    blurred_lap_start, run_into, step_errors_to_truth, synth_then_run, INLINE_SUPERPOINT_ANMS,
    INLINE_SUPERPOINT_ANMS_ONE_LOOK,
};
use common::temp_dir::TempDir;

/// Frames run: past the first corner.
const FRAMES: usize = 32;
/// The corner's blurred frames, the first of which one level loses.
const CORNER: std::ops::RangeInclusive<usize> = 21..=24;
/// The largest error of a frame's pose tracked on the second look,
/// relative to the frame before, against the truth: 0.038 m and 0.81°
/// measured (frame 21); bounds at 2.6× and 1.9×, room for another CPU's
/// int8 network (the odometry steps of the same corner on one level are
/// 0.06-0.18 m off).
const MAX_STEP_ERROR_M: f64 = 0.1;
const MAX_STEP_ERROR_DEG: f64 = 1.5;

#[test]
fn a_blurred_frame_lost_on_one_level_is_tracked_on_the_second_look() {
    if !common::model_available("a_blurred_frame_lost_on_one_level_is_tracked_on_the_second_look") {
        return;
    }
    let dir = TempDir::new("second-look", "stereo");
    let (report, _) = blurred_lap_start(dir.path(), 2, FRAMES, &INLINE_SUPERPOINT_ANMS);
    let records = report["frames"].as_array().expect("per-frame records");
    assert_eq!(records.len(), FRAMES);
    let looked: Vec<String> = records
        .iter()
        .filter(|r| !r["second_look"].is_null())
        .map(|r| {
            format!(
                "{}: {} {} {}",
                r["index"], r["second_look"], r["method"], r["inliers"]
            )
        })
        .collect();
    eprintln!("second looks: {looked:?}");
    let corner: Vec<usize> = CORNER
        .filter(|&i| records[i]["second_look"] == "tracked")
        .collect();
    assert!(
        !corner.is_empty(),
        "none of the corner's frames was tracked on the second look"
    );
    for &k in &corner {
        assert_eq!(records[k]["state"], "Ok");
        // The step below is from a tracked frame.
        assert_eq!(records[k - 1]["state"], "Ok", "frame {}", k - 1);
        assert!(
            records[k]["inliers"].as_u64().unwrap_or(0) >= 30,
            "frame {k}: {}",
            records[k]
        );
    }
    let tracked_on_second_look = records
        .iter()
        .filter(|r| r["second_look"] == "tracked")
        .count() as u64;
    assert_eq!(
        report["summary"]["tracked_on_second_look"].as_u64(),
        Some(tracked_on_second_look),
        "the summary counts the frames tracked on the second look"
    );
    assert!(report["summary"]["second_looks"].as_u64() >= Some(tracked_on_second_look));
    assert_eq!(report["summary"]["second_look_levels"].as_u64(), Some(4));
    // Their poses against the truth, relative to the frame before.
    for (k, metres, degrees) in step_errors_to_truth(dir.path(), &corner) {
        assert!(
            metres <= MAX_STEP_ERROR_M && degrees <= MAX_STEP_ERROR_DEG,
            "frame {k}: step {metres:.3} m, {degrees:.2}° off the truth"
        );
    }
}

/// The blacked-out lap's start (`spslam synth --scene loop --condition
/// blackout --frames 48`: frames 24-31 black), with and without the second
/// look. Tracking loses the black frames; the first five (before the
/// patience) get a second look, which on a black image finds nothing on
/// any pyramid and any CPU. Those looks leave every record and every pose
/// as the run without them has it.
#[test]
fn second_looks_that_find_nothing_change_nothing() {
    if !common::model_available("second_looks_that_find_nothing_change_nothing") {
        return;
    }
    let dir = TempDir::new("second-look", "blackout");
    let dataset = format!("synth:{}", dir.path().display());
    let looked = synth_then_run(
        dir.path(),
        &[
            "--scene",
            "loop",
            "--condition",
            "blackout",
            "--frames",
            "48",
        ],
        &dataset,
        &INLINE_SUPERPOINT_ANMS,
    );
    let one_look_dir = dir.path().join("run_one_look");
    let one_look = run_into(&one_look_dir, &dataset, &INLINE_SUPERPOINT_ANMS_ONE_LOOK);
    let looked_frames: Vec<u64> = looked["frames"]
        .as_array()
        .expect("records")
        .iter()
        .filter(|r| !r["second_look"].is_null())
        .filter_map(|r| r["index"].as_u64())
        .collect();
    eprintln!("second looks at frames {looked_frames:?}");
    assert!(
        looked_frames.len() >= 3 && looked_frames.iter().all(|i| (24..32).contains(i)),
        "second looks at frames {looked_frames:?}, not at the black frames 24-31"
    );
    assert_eq!(
        looked["summary"]["tracked_on_second_look"].as_u64(),
        Some(0)
    );
    assert_eq!(
        looked["summary"]["second_looks"].as_u64(),
        Some(looked_frames.len() as u64)
    );
    assert_eq!(one_look["summary"]["second_looks"].as_u64(), Some(0));
    // Every record without its timings and second-look field.
    let without_looks = |report: &serde_json::Value| {
        let mut frames = report["frames"].clone();
        for r in frames.as_array_mut().expect("records") {
            r["second_look"] = serde_json::Value::Null;
            r["timings"] = serde_json::Value::Null;
            r["loop_check_running"] = serde_json::Value::Null;
            if let Some(mapping) = r["mapping"].as_object_mut() {
                mapping.remove("elapsed_ms");
                mapping.remove("step_ms");
            }
        }
        frames
    };
    assert!(
        without_looks(&looked) == without_looks(&one_look),
        "the second looks changed a record"
    );
    let trajectory = |d: &std::path::Path| {
        std::fs::read_to_string(d.join("trajectory_kitti.txt")).expect("trajectory")
    };
    assert!(
        trajectory(&dir.path().join("run")) == trajectory(&one_look_dir),
        "the second looks changed the trajectory"
    );
}
