//! RGB-D SLAM on real handheld indoor data: Microsoft 7-Scenes "kitchen",
//! frames 0–149 of the excerpt (Kinect v1, depth in millimetres, not
//! registered to colour), through `spslam run` with the shipped
//! `settings/SevenScenes.yaml`, SuperPoint + ANMS (the defaults) beside ORB
//! in the same system: every frame tracked, the ATE, and the keyframe rate.
//!
//! Measured (Intel Xeon with AVX-512 VNNI, 8-bit int8 model, mapping
//! inline): SuperPoint + ANMS 15 keyframes, ATE 0.0173 m; ORB 9
//! keyframes, ATE 0.0161 m. Under ORB-SLAM3's `NeedNewKeyFrame` alone
//! SuperPoint made 125 keyframes (ORB 12), and 31 while a stereo or RGB-D
//! keyframe's peak was raised by the frames after it (before
//! `tracking::keyframe::next_near_reference_count`), so the keyframe bound
//! (≤ 24: 60 % above the measurement, under 3× ORB's 9) catches either
//! rule's return. The ATE bounds leave 25 % for the other int8 model and
//! CPU kinds.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::temp_dir::TempDir;
use spslam::eval::ate::{alignment_transform, position_errors};
use spslam::eval::io::read_tum;
use spslam::eval::{Alignment, Trajectory};

/// Frames of the excerpt run (half of it: the suite's time).
const FRAMES: &str = "150";
/// The RMSE bound of the frames between the monocular initial views,
/// metres: twice the measured 0.0053 m (ORB is the same on every CPU kind;
/// the camera moves 2.4 cm over those frames, and rows left at the first
/// view's pose would be 0.013 m off, rows turned the wrong way more).
const BETWEEN_BOUND_M: f64 = 0.010;

/// What one run's `report.json` says.
#[derive(Debug)]
struct Outcome {
    tracked: u64,
    lost: u64,
    keyframes_inserted: u64,
    ate_se3_m: f64,
}

/// `spslam run` on the kitchen frames (RGB-D, mapping inline so that the
/// run is deterministic, no loop closing: the excerpt has no revisit).
fn run(kitchen: &Path, extractor: &str) -> Outcome {
    let out = TempDir::new("sevenscenes", extractor);
    let text = run_into(kitchen, "rgbd", extractor, out.path());
    let report: serde_json::Value =
        serde_json::from_str(&text).unwrap_or_else(|e| panic!("report.json: {e}"));
    let count = |key: &str| {
        report["summary"][key]
            .as_u64()
            .unwrap_or_else(|| panic!("summary.{key} missing in {text}"))
    };
    Outcome {
        tracked: count("tracked"),
        lost: count("lost"),
        keyframes_inserted: count("keyframes_inserted"),
        ate_se3_m: report["evaluation"]["ate"]["se3_rmse"]
            .as_f64()
            .unwrap_or_else(|| panic!("evaluation.ate.se3_rmse missing in {text}")),
    }
}

/// `spslam run` on the kitchen frames with `sensor` into `out`; returns
/// the text of its `report.json`.
fn run_into(kitchen: &Path, sensor: &str, extractor: &str, out: &Path) -> String {
    let output = Command::new(env!("CARGO_BIN_EXE_spslam"))
        .arg("run")
        .arg("--dataset")
        .arg(format!("tum:{}", kitchen.display()))
        .args(["--sensor", sensor, "--extractor", extractor])
        .arg("--settings")
        .arg(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/settings/SevenScenes.yaml"
        ))
        .args(["--inline-mapping", "--no-loop-closing", "--frames", FRAMES])
        .arg("--out")
        .arg(out)
        .output()
        .unwrap_or_else(|e| panic!("spslam run: {e}"));
    assert!(
        output.status.success(),
        "spslam run --sensor {sensor} --extractor {extractor}: {}\n{}",
        output.status,
        String::from_utf8_lossy(&output.stderr)
    );
    let path = out.join("report.json");
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// This test binary's name, for the data and model checks.
const TEST: &str = "slam_sevenscenes";

/// The kitchen excerpt, or `None` where it is missing outside CI (under
/// CI a missing excerpt fails the test).
fn kitchen() -> Option<PathBuf> {
    let kitchen = common::shared_data_root().join("sevenscenes/kitchen_first300");
    if kitchen.join("rgb.txt").is_file() {
        Some(kitchen)
    } else {
        common::missing(TEST, &format!("{}", kitchen.display()));
        None
    }
}

#[test]
fn kitchen_rgbd_tracks_every_frame_superpoint_beside_orb() {
    let Some(kitchen) = kitchen() else {
        return;
    };
    if !common::model_available(TEST) {
        return;
    }
    let superpoint = run(&kitchen, "superpoint");
    let orb = run(&kitchen, "orb");
    eprintln!("SuperPoint + ANMS: {superpoint:?}\nORB: {orb:?}");
    for (name, o) in [("SuperPoint", &superpoint), ("ORB", &orb)] {
        assert_eq!((o.tracked, o.lost), (150, 0), "{name}: {o:?}");
    }
    assert!(
        superpoint.keyframes_inserted <= 24,
        "SuperPoint keyframes (measured 15; 31 with the peak raised after the keyframe, 125 under ORB-SLAM3's rule alone): {superpoint:?}"
    );
    assert!(
        orb.keyframes_inserted <= 12,
        "ORB keyframes (measured 9; 12 under ORB-SLAM3's rule alone): {orb:?}"
    );
    assert!(superpoint.ate_se3_m <= 0.022, "SuperPoint: {superpoint:?}");
    assert!(orb.ate_se3_m <= 0.021, "ORB: {orb:?}");
}

/// The kitchen, monocular, ORB: the handheld camera moves slowly, so the
/// two-view initialisation waits for parallax over many frames
/// (ORB-SLAM3's `MonocularInitialization` gives them no pose). Once the
/// map exists, every frame between the two views is localised in it
/// (`tracking::between_views`), so every frame has a pose from the map,
/// as accurate as the frames tracked live after it: the whole run is
/// aligned to the ground truth on the live frames alone (Sim(3)) and the
/// frames between the views are judged in that alignment.
///
/// Measured (Intel Xeon, ORB, mapping inline, 150 frames): views 0 and
/// 20, all 19 frames between localised; in the alignment on the live
/// frames (scale 2.037) the live frames' RMSE is 0.0184 m and the frames
/// between the views' 0.0053 m. Before, those 19 frames were counted as
/// not initialised and had only a coasted row.
#[test]
fn kitchen_monocular_localises_the_frames_between_its_initial_views() {
    let Some(kitchen) = kitchen() else {
        return;
    };
    let out = TempDir::new("sevenscenes", "mono");
    let text = run_into(&kitchen, "mono", "orb", out.path());
    let report: serde_json::Value =
        serde_json::from_str(&text).unwrap_or_else(|e| panic!("report.json: {e}"));
    let frames = report["frames"]
        .as_array()
        .unwrap_or_else(|| panic!("frames missing in report.json"));
    let with_method = |method: &str| -> Vec<usize> {
        frames
            .iter()
            .filter(|f| f["method"] == method)
            .filter_map(|f| f["index"].as_u64())
            .map(|i| i as usize)
            .collect()
    };
    let views = with_method("Initialisation");
    let between = with_method("BetweenInitialViews");
    let tracked = frames.iter().filter(|f| f["state"] == "Ok").count();
    eprintln!("initial views {views:?}; localised between them: {between:?}; tracked {tracked}");
    let [first, second] = views[..] else {
        panic!("expected one monocular initialisation (two views), got {views:?}");
    };
    assert!(
        second > first + 10,
        "views {first} and {second}: too few frames between to test"
    );
    assert_eq!(
        between,
        (first + 1..second).collect::<Vec<_>>(),
        "every frame between the views localised"
    );
    assert_eq!(tracked, frames.len(), "every frame has a pose from the map");
    assert_eq!(
        report["summary"]["between_initial_views"].as_u64(),
        Some(between.len() as u64),
        "the summary counts them"
    );

    let ok = |r: Result<Trajectory, spslam::eval::EvalError>| r.unwrap_or_else(|e| panic!("{e}"));
    let estimate = ok(read_tum(&out.path().join("trajectory_tum.txt")));
    let truth = ok(read_tum(&kitchen.join("groundtruth.txt")));
    let truth = truth.select(&(0..estimate.len()).collect::<Vec<_>>());
    let live: Vec<usize> = (second..estimate.len()).collect();
    let sim = alignment_transform(
        &truth.select(&live),
        &estimate.select(&live),
        Alignment::Sim3,
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let errors = position_errors(&truth, &estimate.transformed(&sim.transform, sim.scale));
    let rmse = |rows: &[usize]| {
        (rows.iter().map(|&i| errors[i] * errors[i]).sum::<f64>() / rows.len() as f64).sqrt()
    };
    let (live_rmse, between_rmse) = (rmse(&live), rmse(&between));
    eprintln!(
        "Sim(3) on the live frames (scale {:.3}): live RMSE {live_rmse:.4} m, between the views {between_rmse:.4} m",
        sim.scale
    );
    assert!(
        between_rmse <= BETWEEN_BOUND_M,
        "between the views: {between_rmse:.4} m"
    );
}
