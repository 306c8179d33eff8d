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

use std::path::Path;
use std::process::Command;

use common::temp_dir::TempDir;

/// Frames of the excerpt run (half of it: the suite's time).
const FRAMES: &str = "150";

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
    let output = Command::new(env!("CARGO_BIN_EXE_spslam"))
        .arg("run")
        .arg("--dataset")
        .arg(format!("tum:{}", kitchen.display()))
        .args(["--sensor", "rgbd", "--extractor", extractor])
        .arg("--settings")
        .arg(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/settings/SevenScenes.yaml"
        ))
        .args(["--inline-mapping", "--no-loop-closing", "--frames", FRAMES])
        .arg("--out")
        .arg(out.path())
        .output()
        .unwrap_or_else(|e| panic!("spslam run: {e}"));
    assert!(
        output.status.success(),
        "spslam run --extractor {extractor}: {}\n{}",
        output.status,
        String::from_utf8_lossy(&output.stderr)
    );
    let path = out.path().join("report.json");
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let report: serde_json::Value =
        serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
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

#[test]
fn kitchen_rgbd_tracks_every_frame_superpoint_beside_orb() {
    let test = "slam_sevenscenes";
    let kitchen = common::shared_data_root().join("sevenscenes/kitchen_first300");
    if !kitchen.join("rgb.txt").is_file() {
        common::missing(test, &format!("{}", kitchen.display()));
        return;
    }
    if !common::model_available(test) {
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
