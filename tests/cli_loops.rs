//! `spslam loops` end to end on the shared data: the EuRoC loop pair is
//! found among unrelated KITTI frames, the excerpts without revisits give no
//! loop, and bad input fails with a message naming it. Also
//! `spslam vocab train --format vlad`.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use spslam::features::ExtractorConfig;
use spslam::place::{extractor_settings_hash, Codebook, GlobalDescriptor};
use spslam::settings::{ExtractorSettings, DEFAULT_SUPERPOINT_LEVELS};

fn spslam() -> Command {
    Command::new(env!("CARGO_BIN_EXE_spslam"))
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("spslam-cli-loops-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn assert_success(out: &Output) -> String {
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

/// Runs `spslam loops` on `dir` and returns (stdout, the JSON report).
fn loops(dir: &Path, extra: &[&str]) -> (String, serde_json::Value) {
    let json = dir.with_extension("json");
    let out = spslam()
        .args(["loops", "--images"])
        .arg(dir)
        .arg("--json")
        .arg(&json)
        .args(extra)
        .output()
        .unwrap();
    let stdout = assert_success(&out);
    let text = std::fs::read_to_string(&json).unwrap();
    (stdout, serde_json::from_str(&text).unwrap())
}

/// Every accepted match as (query image, matched image, score, inliers).
fn accepted(report: &serde_json::Value) -> Vec<(String, String, f64, u64)> {
    let mut all = Vec::new();
    for image in report["images"].as_array().unwrap() {
        for m in image["matches"].as_array().unwrap() {
            all.push((
                image["image"].as_str().unwrap().to_string(),
                m["image"].as_str().unwrap().to_string(),
                m["score"].as_f64().unwrap(),
                m["inliers"].as_u64().unwrap(),
            ));
        }
    }
    all
}

fn link(from: &Path, to: &Path) {
    #[cfg(unix)]
    std::os::unix::fs::symlink(from, to).unwrap();
    #[cfg(not(unix))]
    std::fs::copy(from, to).unwrap();
}

/// The data and the model, or `None` (skipped, or a failure under CI).
fn data(test: &str) -> Option<PathBuf> {
    let root = common::data_dir(test)?;
    if !common::model_available(test) {
        return None;
    }
    let pairs = root.join("euroc/V1_01_easy_loop_pairs/pairs.txt");
    let euroc = root.join("euroc/V1_01_easy_first95/mav0/cam0/data");
    if !pairs.is_file() || !euroc.is_dir() {
        common::missing(test, "the EuRoC loop pairs and excerpt");
        return None;
    }
    Some(root)
}

#[test]
fn finds_the_euroc_loop_pair_among_unrelated_frames() {
    let Some(root) = data("finds_the_euroc_loop_pair_among_unrelated_frames") else {
        return;
    };
    let pairs = root.join("euroc/V1_01_easy_loop_pairs");
    let dir = temp_dir("pair");
    // match1, 12 KITTI frames, query1 (98 s later, same place), then
    // match2 and query2 (0.5 s apart: not a loop).
    link(&pairs.join("left_img_0.png"), &dir.join("00_match1.png"));
    for i in 0..12 {
        let name = format!("{:06}.png", i * 4);
        link(
            &root.join("kitti/sequences/06/image_0").join(&name),
            &dir.join(format!("{:02}_kitti_{name}", i + 1)),
        );
    }
    link(&pairs.join("left_img_1.png"), &dir.join("13_query1.png"));
    link(&pairs.join("left_img_2.png"), &dir.join("14_match2.png"));
    link(&pairs.join("left_img_3.png"), &dir.join("15_query2.png"));
    let (stdout, report) = loops(&dir, &[]);
    println!("{stdout}");
    assert_eq!(report["images"].as_array().unwrap().len(), 16);
    let found = accepted(&report);
    assert_eq!(found.len(), 1, "exactly the true loop: {found:?}");
    let (query, matched, score, inliers) = &found[0];
    assert_eq!(
        (query.as_str(), matched.as_str()),
        ("13_query1.png", "00_match1.png")
    );
    assert!(*score > 0.0 && *score <= 1.0 && *inliers >= 60, "{found:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Runs `spslam loops --dataset` and returns (stdout, the curves JSON).
fn judged(name: &str, dataset: &str, extra: &[&str]) -> (String, serde_json::Value) {
    let dir = temp_dir(name);
    let curves = dir.join("curves.json");
    let out = spslam()
        .args(["loops", "--dataset", dataset, "--curves"])
        .arg(&curves)
        .args(extra)
        .output()
        .unwrap();
    let stdout = assert_success(&out);
    let report = serde_json::from_str(&std::fs::read_to_string(&curves).unwrap()).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    (stdout, report)
}

/// The acceptance threshold the run used, as it printed it
/// ("accepted: >= N inliers"): the tool's default unless overridden.
fn printed_min_inliers(stdout: &str) -> u64 {
    let after = stdout
        .split("accepted: >= ")
        .nth(1)
        .unwrap_or_else(|| panic!("no threshold printed: {stdout}"));
    after
        .split_whitespace()
        .next()
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no threshold printed: {stdout}"))
}

/// Candidates with at least `min_inliers`, by their ground truth:
/// (same place, another place).
fn accepted_by_truth(report: &serde_json::Value, min_inliers: u64) -> (Vec<u64>, Vec<String>) {
    let mut same_queries = Vec::new();
    let mut wrong = Vec::new();
    for c in report["candidates"].as_array().unwrap() {
        if c["inliers"].as_u64().unwrap() < min_inliers {
            continue;
        }
        match c["truth"].as_str().unwrap() {
            "same" => same_queries.push(c["query"].as_u64().unwrap()),
            "different" => wrong.push(c.to_string()),
            _ => {}
        }
    }
    same_queries.sort_unstable();
    same_queries.dedup();
    (same_queries, wrong)
}

#[test]
fn no_loops_on_the_excerpts_without_revisits() {
    let Some(root) = data("no_loops_on_the_excerpts_without_revisits") else {
        return;
    };
    // KITTI 06 (51 frames, no revisit), judged by its ground truth and its
    // stereo depth: no candidate showing another place is accepted.
    // Measured (AMD EPYC, AVX2): 66 candidates judged; the best candidate
    // showing another place has 9 inliers; those at or above the default
    // (the best: 43, frames 14 -> 3) overlap the query's view by 0.3-0.5:
    // the same street 10 frames back, not a false match.
    let kitti = format!("kitti:{}", root.join("kitti/sequences/06").display());
    let (stdout, report) = judged("judged-kitti", &kitti, &[]);
    println!("{stdout}");
    assert_eq!(report["images"], 51);
    assert_eq!(report["revisiting_queries"].as_array().unwrap().len(), 0);
    let candidates = report["candidates"].as_array().unwrap();
    assert!(candidates.len() >= 40, "{} candidates", candidates.len());
    assert!(candidates.iter().all(|c| c["truth"].is_string()));
    let (_, wrong) = accepted_by_truth(&report, printed_min_inliers(&stdout));
    assert!(wrong.is_empty(), "false matches accepted: {wrong:?}");

    // The EuRoC V1_01 excerpt: the MAV hovers, every earlier frame is
    // covisible, nothing is searched or accepted.
    let dir = root.join("euroc/V1_01_easy_first95/mav0/cam0/data");
    let json_dir = temp_dir("excerpt");
    let json = json_dir.join("loops.json");
    let out = spslam()
        .args(["loops", "--images"])
        .arg(&dir)
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    let stdout = assert_success(&out);
    println!("{stdout}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(report["images"].as_array().unwrap().len(), 95);
    assert_eq!(accepted(&report), vec![], "{}", dir.display());
    std::fs::remove_dir_all(&json_dir).unwrap();
}

/// A synthetic lap (80 frames, 320x240) whose camera is carried back 20 m
/// halfway (`--condition jump-back`): the frames after the jump revisit
/// the places of 20 frames before, exactly. Measured (AMD EPYC, AVX2):
/// 29 of 100 frames revisit; 206 candidates judged, none showing another
/// place with 8 or more inliers; at the then default (50 inliers, groups
/// of 10 neighbours), recall 0.72 (21 of 29) and precision 1. With today's
/// defaults (60 inliers, no groups; Intel Xeon, VNNI): none false with 7
/// or more inliers, recall 0.72 (21 of 29), 0.83 at 15. Bounds: 20-40 revisiting frames (the
/// covisibility stand-in depends on the network's output), recall >= 0.6,
/// no false match at the default.
#[test]
fn a_kidnapped_lap_is_found_again_and_judged_by_its_ground_truth() {
    if !common::model_available("a_kidnapped_lap_is_found_again_and_judged_by_its_ground_truth") {
        return;
    }
    let dir = temp_dir("jump");
    let out = spslam()
        .args([
            "synth",
            "--scene",
            "loop",
            "--frames",
            "80",
            "--condition",
            "jump-back",
        ])
        .args(["--size", "320x240", "--focal", "200", "--out"])
        .arg(&dir)
        .output()
        .unwrap();
    assert_success(&out);
    let (stdout, report) = judged("judged-jump", &format!("synth:{}", dir.display()), &[]);
    println!("{stdout}");
    assert_eq!(report["images"], 100);
    let revisiting: Vec<u64> = report["revisiting_queries"]
        .as_array()
        .unwrap()
        .iter()
        .map(|q| q.as_u64().unwrap())
        .collect();
    assert!((20..=40).contains(&revisiting.len()), "{revisiting:?}");
    // Every revisit comes after the jump (frame 40 of the lap).
    assert!(revisiting.iter().all(|&q| q >= 40), "{revisiting:?}");
    let min_inliers = printed_min_inliers(&stdout);
    assert_eq!(
        min_inliers, 60,
        "the default changed: re-measure the bounds"
    );
    let (found, wrong) = accepted_by_truth(&report, min_inliers);
    assert!(wrong.is_empty(), "false matches accepted: {wrong:?}");
    let hits = found.iter().filter(|q| revisiting.contains(q)).count();
    let recall = hits as f64 / revisiting.len() as f64;
    assert!(
        recall >= 0.6,
        "recall {recall}: {found:?} of {revisiting:?}"
    );
    // The printed curves: one table per rule.
    assert_eq!(report["curves"].as_array().unwrap().len(), 4);
    assert!(
        stdout.contains("lowest threshold with no false match"),
        "{stdout}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_input_and_a_foreign_codebook_fail_with_a_message() {
    let Some(root) = data("bad_input_and_a_foreign_codebook_fail_with_a_message") else {
        return;
    };
    let dir = temp_dir("bad");
    std::fs::write(dir.join("broken.png"), b"not a png").unwrap();
    let out = spslam()
        .args(["loops", "--images"])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("broken.png"), "{stderr}");

    // --dataset: EuRoC's ground truth is the body's, and a camera alone
    // needs a nominal depth; both are refused with what to do.
    let euroc = format!("euroc:{}", root.join("euroc/V1_01_easy_first95").display());
    let out = spslam()
        .args(["loops", "--dataset", &euroc])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("body (IMU) pose"), "{stderr}");
    let kitti07 = format!("kitti:{}", root.join("kitti/sequences/07").display());
    let out = spslam()
        .args(["loops", "--dataset", &kitti07])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("--truth-depth"), "{stderr}");

    // A codebook trained for other descriptors (the fp32 network; the
    // default is int8) is refused. The feature count does not matter.
    let book = dir.join("small.spvlad");
    let out = spslam()
        .args([
            "vocab", "train", "--format", "vlad", "--k", "4", "--pca", "2",
        ])
        .args([
            "--max-images",
            "3",
            "--features",
            "300",
            "--precision",
            "fp32",
        ])
        .arg("--images")
        .arg(root.join("kitti/sequences/06/image_0"))
        .arg("--out")
        .arg(&book)
        .output()
        .unwrap();
    let stdout = assert_success(&out);
    assert!(stdout.contains("k = 4"), "{stdout}");
    let codebook = Codebook::load(&book).unwrap();
    assert_eq!(codebook.vlad.k(), 4);
    assert_eq!(codebook.vlad.dim(), 2);
    let settings = ExtractorSettings {
        n_features: 300,
        precision: spslam::features::Precision::Fp32,
        ..ExtractorSettings::default()
    };
    let expected: ExtractorConfig = settings.superpoint_config(DEFAULT_SUPERPOINT_LEVELS, 1);
    assert_eq!(codebook.settings_hash, extractor_settings_hash(&expected));

    std::fs::remove_file(dir.join("broken.png")).unwrap();
    link(
        &root.join("kitti/sequences/06/image_0/000000.png"),
        &dir.join("a.png"),
    );
    let out = spslam()
        .args(["loops", "--images"])
        .arg(&dir)
        .arg("--codebook")
        .arg(&book)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("small.spvlad") && stderr.contains("trained for extractor settings"),
        "{stderr}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
