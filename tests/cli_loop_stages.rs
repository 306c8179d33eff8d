//! `spslam run --record-loop-stages` end to end: one lap of the synthetic
//! city block at 320×240 (the soak run's size), SuperPoint on one level.
//! The lap ends where it began, so the run closes a loop; `report.json`'s
//! `loop_candidates` holds every candidate the database proposed with each
//! stage's count and, from the sequence's ground truth, its registration's
//! truth.
//!
//! A second run: the first 40 frames of the same lap with every façade the
//! same grid of windows (`--condition repeated-texture`), RGB-D. Round
//! frame 30 the walls after the first corner look like those before it,
//! a quarter turn and about 23 m away. Before the drift stage existed the
//! standard set closed this as a false loop (frame 29 → 3, EVALUATION.md).
//! While tracking slipped a façade period at a time (until session 54's
//! step limit, `StepLimit` in `src/tracking/tracker.rs`) such look-alikes
//! registered with 110–120 inliers and passed every count stage, and the
//! drift stage stopped them (frames 29, 32, 35 and 38); on the map tracked
//! without slipping the same look-alikes fail at RANSAC (12–28 inliers).
//! No loop may close, every registration judged must be a different place,
//! and a look-alike that passes every count stage must be stopped by the
//! drift stage. The drift stage's own rule is tested in
//! `src/loop_closing/drift.rs` and `stage_counts.rs`; in the standard set
//! it stops a look-alike on the repeated-texture lap in stereo (frame
//! 208 → 103).

mod common;

use common::cli::{logs, spslam};
use common::temp_dir::TempDir;

/// A synthetic scene written by `spslam synth` with `synth_args` into a
/// fresh folder, then `spslam run --inline-mapping --record-loop-stages`
/// over it (`dataset`: the `--dataset` value from the folder) with
/// `run_args`: the run's `report.json` and its output.
fn synth_and_run(
    tag: &str,
    synth_args: &[&str],
    dataset: impl Fn(&std::path::Path) -> String,
    run_args: &[&str],
) -> (serde_json::Value, String, TempDir) {
    let dir = TempDir::new("loop-stages", tag);
    let synth = spslam()
        .arg("synth")
        .arg("--out")
        .arg(dir.path())
        .args(synth_args)
        .output()
        .expect("run spslam synth");
    assert!(synth.status.success(), "{}", logs(&synth));
    let out = dir.path().join("run");
    let run = spslam()
        .arg("run")
        .arg("--dataset")
        .arg(dataset(dir.path()))
        .args(["--inline-mapping", "--record-loop-stages"])
        .args(run_args)
        .arg("--out")
        .arg(&out)
        .output()
        .expect("run spslam run");
    assert_eq!(run.status.code(), Some(0), "{}", logs(&run));
    let text = std::fs::read_to_string(out.join("report.json")).expect("report.json written");
    let report = serde_json::from_str(&text).expect("report.json parses");
    (report, logs(&run), dir)
}

#[test]
fn every_loop_candidate_is_recorded_with_its_counts_and_judged() {
    if !common::model_available("every_loop_candidate_is_recorded_with_its_counts_and_judged") {
        return;
    }
    let (report, run_logs, _dir) = synth_and_run(
        "lap",
        &[
            "--scene",
            "loop",
            "--size",
            "320x240",
            "--focal",
            "200",
            "--no-depth",
        ],
        |dir| format!("synth:{}", dir.display()),
        &["--levels", "1"],
    );
    let loops = report["loops"].as_array().expect("loops");
    assert!(!loops.is_empty(), "the lap closes no loop: {run_logs}");
    let candidates = report["loop_candidates"]
        .as_array()
        .expect("loop_candidates recorded");
    let stage_names = [
        "descriptor_matches",
        "ransac",
        "pose_optimisation",
        "projection",
        "reprojection",
        "drift",
    ];
    for c in candidates {
        let counts = &c["counts"];
        assert!(counts["descriptor_matches"].as_u64().is_some(), "{c}");
        match c["rejected_at"].as_str() {
            None => {
                // Passed: every stage ran, and the truth judged it right.
                assert!(counts["reprojection_inliers"].as_u64() >= Some(80), "{c}");
                assert_eq!(c["truth"], "same", "{c}");
                assert!(c["registration_error_m"].as_f64() <= Some(1.0), "{c}");
            }
            Some(stage) => assert!(stage_names.contains(&stage), "{c}"),
        }
        // A registration is judged exactly when the check reached a pose.
        assert_eq!(
            c["truth"].is_null(),
            c["candidate_in_query"].is_null(),
            "{c}"
        );
    }
    // The loop's candidate is among them, passed.
    let loop_match = loops[0]["match_frame"].as_u64().expect("match_frame");
    assert!(
        candidates.iter().any(
            |c| c["candidate_frame"].as_u64() == Some(loop_match) && c["rejected_at"].is_null()
        ),
        "the loop to frame {loop_match} is not among the recorded candidates"
    );
}

#[test]
fn no_look_alike_on_repeated_texture_closes_a_loop() {
    if !common::model_available("no_look_alike_on_repeated_texture_closes_a_loop") {
        return;
    }
    let (report, _, _dir) = synth_and_run(
        "repeated",
        &[
            "--scene",
            "loop",
            "--condition",
            "repeated-texture",
            "--frames",
            "40",
        ],
        |dir| format!("tum:{}", dir.join("sequences/00").display()),
        &[],
    );

    // The run never revisits a place: no loop may be closed.
    let loops = report["loops"].as_array().expect("loops");
    assert!(loops.is_empty(), "false loops closed: {loops:?}");
    let candidates = report["loop_candidates"]
        .as_array()
        .expect("loop_candidates recorded");
    let count = |c: &serde_json::Value, stage: &str| c["counts"][stage].as_u64().unwrap_or(0);
    let passes_every_count = |c: &serde_json::Value| {
        count(c, "descriptor_matches") >= 20
            && count(c, "optimised_inliers") >= 20
            && count(c, "projection_matches") >= 50
            && count(c, "reprojection_inliers") >= 80
            && !matches!(
                c["rejected_at"].as_str(),
                Some(
                    "descriptor_matches"
                        | "ransac"
                        | "pose_optimisation"
                        | "projection"
                        | "reprojection"
                )
            )
    };
    assert!(!candidates.is_empty(), "the look-alikes were not proposed");
    for c in candidates {
        assert!(!c["rejected_at"].is_null(), "a look-alike passed: {c}");
        if !c["truth"].is_null() {
            assert_eq!(c["truth"], "different", "{c}");
        }
    }
    let stopped: Vec<&serde_json::Value> = candidates
        .iter()
        .filter(|c| passes_every_count(c))
        .collect();
    eprintln!(
        "{} candidates, {} passed every count stage",
        candidates.len(),
        stopped.len()
    );
    for c in stopped {
        assert_eq!(c["truth"], "different", "{c}");
        assert_eq!(c["rejected_at"], "drift", "{c}");
        // The correction asked for is far beyond drift: over 40% of the way.
        let drift = &c["counts"]["drift"];
        let (moved, path) = (
            drift["correction_m"].as_f64().expect("correction_m"),
            drift["travel"]["path_m"].as_f64().expect("path_m"),
        );
        assert!(moved > 0.4 * path, "{c}");
    }
}
