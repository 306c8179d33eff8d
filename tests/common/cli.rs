//! Running the `spslam` binary from a test.

use std::process::{Command, Output};

/// `spslam run` arguments: local mapping inline (deterministic),
/// SuperPoint + ANMS with the defaults.
#[allow(dead_code)]
pub const INLINE_SUPERPOINT_ANMS: [&str; 5] = [
    "--inline-mapping",
    "--extractor",
    "superpoint",
    "--anms",
    "kdtree",
];

/// [`INLINE_SUPERPOINT_ANMS`] without the second look at lost frames
/// (`--second-look-levels 0`).
pub const INLINE_SUPERPOINT_ANMS_ONE_LOOK: [&str; 7] = [
    "--inline-mapping",
    "--extractor",
    "superpoint",
    "--anms",
    "kdtree",
    "--second-look-levels",
    "0",
];

/// A command for the `spslam` binary Cargo built for the tests.
pub fn spslam() -> Command {
    Command::new(env!("CARGO_BIN_EXE_spslam"))
}

/// A finished command's stdout and stderr, for an assertion's message.
pub fn logs(output: &Output) -> String {
    format!(
        "stdout:\n{}\nstderr:\n{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    )
}

/// Writes a synthetic sequence into `dir` (`spslam synth SYNTH_ARGS --out
/// DIR`), runs `spslam run --dataset DATASET RUN_ARGS --out DIR/run` over
/// it, asserts that both succeed, and returns the run's `report.json`.
pub fn synth_then_run(
    dir: &std::path::Path,
    synth_args: &[&str],
    dataset: &str,
    run_args: &[&str],
) -> serde_json::Value {
    let synth = spslam()
        .arg("synth")
        .args(synth_args)
        .arg("--out")
        .arg(dir)
        .output()
        .expect("run spslam synth");
    assert!(synth.status.success(), "{}", logs(&synth));
    run_into(&dir.join("run"), dataset, run_args)
}

/// Runs `spslam run --dataset DATASET RUN_ARGS --out OUT`, asserts that it
/// succeeds, and returns its `report.json`.
pub fn run_into(out: &std::path::Path, dataset: &str, run_args: &[&str]) -> serde_json::Value {
    let run = spslam()
        .args(["run", "--dataset", dataset])
        .args(run_args)
        .arg("--out")
        .arg(out)
        .output()
        .expect("run spslam run");
    assert_eq!(run.status.code(), Some(0), "{}", logs(&run));
    let text = std::fs::read_to_string(out.join("report.json")).expect("report.json written");
    serde_json::from_str(&text).expect("report.json parses")
}

/// A run report's per-frame records, the indices of the frames not
/// tracked, and the maps its frames lie in.
pub fn frames_lost_and_maps(
    report: &serde_json::Value,
) -> (
    &Vec<serde_json::Value>,
    Vec<u64>,
    std::collections::BTreeSet<u64>,
) {
    let records = report["frames"].as_array().expect("per-frame records");
    let lost = records
        .iter()
        .filter(|r| r["state"] != "Ok")
        .filter_map(|r| r["index"].as_u64())
        .collect();
    let maps = records.iter().filter_map(|r| r["map"].as_u64()).collect();
    (records, lost, maps)
}

/// The start of the blurred lap (`spslam synth --scene loop --blur 6
/// --seed SEED --frames FRAMES` into `dir`), run with `run_args` into
/// `dir/run`: its `report.json` and the `--dataset` it was run on.
pub fn blurred_lap_start(
    dir: &std::path::Path,
    seed: u32,
    frames: usize,
    run_args: &[&str],
) -> (serde_json::Value, String) {
    let (seed, frames) = (seed.to_string(), frames.to_string());
    let dataset = format!("synth:{}", dir.display());
    let synth = [
        "--scene", "loop", "--blur", "6", "--seed", &seed, "--frames", &frames,
    ];
    (synth_then_run(dir, &synth, &dataset, run_args), dataset)
}

/// Each of `frames`' pose relative to the frame before, in `dir/run`'s
/// trajectory, against the same step in the synthetic scene's truth
/// (`dir/poses/00.txt`): (frame, metres, degrees), printed.
pub fn step_errors_to_truth(dir: &std::path::Path, frames: &[usize]) -> Vec<(usize, f64, f64)> {
    use spslam::eval::read_kitti;
    let estimate = read_kitti(&dir.join("run/trajectory_kitti.txt")).expect("trajectory");
    let truth = read_kitti(&dir.join("poses/00.txt")).expect("ground truth");
    assert_eq!(estimate.poses.len(), truth.poses.len(), "one row per frame");
    frames
        .iter()
        .map(|&k| {
            let step = estimate.poses[k - 1].inverse() * estimate.poses[k];
            let true_step = truth.poses[k - 1].inverse() * truth.poses[k];
            let error = true_step.inverse() * step;
            let metres = error.translation.vector.norm();
            let degrees = error.rotation.angle().to_degrees();
            eprintln!("frame {k}: step error {metres:.3} m, {degrees:.2}°");
            (k, metres, degrees)
        })
        .collect()
}

/// Asserts that a run's `report` has `frames` per-frame records, every one
/// tracked and all in one map, printing the frames not started by the
/// motion model (`label` names the run in the messages); returns the
/// records.
#[allow(dead_code)]
pub fn assert_every_frame_in_one_map<'a>(
    report: &'a serde_json::Value,
    frames: usize,
    label: &str,
) -> &'a Vec<serde_json::Value> {
    let (records, lost, maps) = frames_lost_and_maps(report);
    assert_eq!(records.len(), frames, "{label}: one record per frame");
    let starts: Vec<String> = records
        .iter()
        .filter(|r| r["method"] != "MotionModel")
        .map(|r| format!("{}: {} {}", r["index"], r["method"], r["inliers"]))
        .collect();
    eprintln!("{label}: lost {lost:?}; maps {maps:?}; other starts {starts:?}");
    assert!(lost.is_empty(), "{label}: frames not tracked: {lost:?}");
    assert_eq!(maps.len(), 1, "{label}: frames in maps {maps:?}");
    records
}

/// The first `frames` frames of the synthetic loop lap under `condition`
/// (`spslam synth --scene loop --condition CONDITION`, 640×480 as in the
/// suite) written into `dir` and run with `--sensor SENSOR` and
/// [`INLINE_SUPERPOINT_ANMS`] into `dir/run`: its `report.json`.
#[allow(dead_code)]
pub fn run_lap_start(
    dir: &std::path::Path,
    condition: &str,
    frames: usize,
    sensor: &str,
) -> serde_json::Value {
    let frame_count = frames.to_string();
    let dataset = format!("synth:{}", dir.display());
    let synth = [
        "--scene",
        "loop",
        "--condition",
        condition,
        "--frames",
        &frame_count,
    ];
    let run = [&["--sensor", sensor][..], &INLINE_SUPERPOINT_ANMS].concat();
    synth_then_run(dir, &synth, &dataset, &run)
}

/// Asserts a run's ATE (SE3) against the scene's truth is at most
/// `max_ate_m`, printing it.
#[allow(dead_code)]
pub fn assert_ate_at_most(report: &serde_json::Value, max_ate_m: f64, label: &str) {
    let ate = report["evaluation"]["ate"]["se3_rmse"].as_f64();
    eprintln!("{label}: ATE (SE3) {ate:?} m");
    let ate = ate.expect("the run is evaluated against the scene's truth");
    assert!(ate <= max_ate_m, "{label}: ATE {ate} m > {max_ate_m} m");
}

/// [`run_lap_start`] in a temporary folder: asserts every frame tracked in
/// one map and an ATE (SE3) of at most `max_ate_m`.
#[allow(dead_code)]
pub fn assert_lap_start_tracked_in_one_map(
    condition: &str,
    frames: usize,
    sensor: &str,
    max_ate_m: f64,
) {
    let dir = super::temp_dir::TempDir::new(condition, sensor);
    let report = run_lap_start(dir.path(), condition, frames, sensor);
    let label = format!("{condition}, {sensor}");
    assert_every_frame_in_one_map(&report, frames, &label);
    assert_ate_at_most(&report, max_ate_m, &label);
}
