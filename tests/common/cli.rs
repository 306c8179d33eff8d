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
