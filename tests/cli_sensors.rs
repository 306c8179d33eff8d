//! `spslam run --sensor` and `--dataset tum:` on a synthetic sequence
//! written by `spslam synth` (ORB features, no model needed): RGB-D from
//! the TUM lists and depth maps, monocular from the left images, a
//! sensor the dataset cannot feed refused, and bad depth images named;
//! SuperPoint's default pyramid per sensor (that test needs the model).

mod common;

use common::temp_dir::TempDir;
use spslam::features::{ModelWeights, Precision};
use std::path::Path;
use std::process::{Command, Output};

const FRAMES: usize = 40;

fn spslam() -> Command {
    Command::new(env!("CARGO_BIN_EXE_spslam"))
}

/// A synthetic sequence with depth maps (and TUM lists): OUT/sequences/00.
fn synth(tag: &str) -> TempDir {
    let dir = TempDir::new("sensors", tag);
    let out = spslam()
        .arg("synth")
        .arg("--out")
        .arg(dir.path())
        .args(["--frames", &FRAMES.to_string(), "--size", "480x360"])
        .output()
        .expect("run spslam synth");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    dir
}

fn run(dataset: &str, out: &Path, extra: &[&str]) -> Output {
    spslam()
        .arg("run")
        .args(["--dataset", dataset])
        .args(["--extractor", "orb", "--inline-mapping", "--out"])
        .arg(out)
        .args(extra)
        .output()
        .expect("run spslam run")
}

/// `spslam run` with ORB and local mapping on its thread.
fn run_threaded(dataset: &str, out: &Path, extra: &[&str]) -> Output {
    spslam()
        .arg("run")
        .args(["--dataset", dataset, "--extractor", "orb", "--out"])
        .arg(out)
        .args(extra)
        .output()
        .expect("run spslam run")
}

fn logs(output: &Output) -> String {
    format!(
        "stdout:\n{}\nstderr:\n{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    )
}

fn report(out: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(out.join("report.json")).expect("report.json written");
    serde_json::from_str(&text).expect("report.json parses")
}

fn tracked(report: &serde_json::Value) -> usize {
    report["frames"]
        .as_array()
        .map_or(0, |f| f.iter().filter(|r| r["state"] == "Ok").count())
}

#[test]
fn tum_folders_run_as_rgbd_and_stereo_sequences_run_as_mono() {
    let data = synth("runs");
    let sequence = data.path().join("sequences/00");
    let tum = format!("tum:{}", sequence.display());

    let out = data.path().join("out-rgbd");
    let output = run(&tum, &out, &[]);
    assert_eq!(output.status.code(), Some(0), "{}", logs(&output));
    let r = report(&out);
    assert_eq!(r["sensor"], "rgbd");
    assert_eq!(tracked(&r), FRAMES, "{}", logs(&output));
    let ate = r["evaluation"]["ate"]["se3_rmse"].as_f64();
    eprintln!("rgbd: ATE {ate:?}");
    assert!(ate.is_some_and(|a| a < 0.5), "{}", logs(&output));
    assert!(out.join("trajectory_tum.txt").is_file());

    // The block's first corner turns 11.5° a frame from frame 21 on, too
    // fast for a monocular map at this 62° field of view (it starts a new
    // map there; see EVALUATION.md): the first 20 frames test the plumbing.
    let out = data.path().join("out-mono");
    let synth_dataset = format!("synth:{}", data.path().display());
    let output = run(
        &synth_dataset,
        &out,
        &["--sensor", "mono", "--frames", "20"],
    );
    assert_eq!(output.status.code(), Some(0), "{}", logs(&output));
    let r = report(&out);
    assert_eq!(r["sensor"], "mono");
    let before = r["frames"].as_array().map_or(usize::MAX, |f| {
        f.iter().take_while(|r| r["state"] != "Ok").count()
    });
    assert!(
        before < 10,
        "initialised after {before} frames: {}",
        logs(&output)
    );
    assert_eq!(tracked(&r), 20 - before, "{}", logs(&output));
    assert!(
        r["scale_drift"]["ratio"].as_f64().is_some(),
        "{}",
        logs(&output)
    );
    assert!(r["drift"].is_null(), "no metric drift for monocular");

    let out = data.path().join("out-synth-rgbd");
    let output = run(
        &synth_dataset,
        &out,
        &["--sensor", "rgbd", "--frames", "10"],
    );
    assert_eq!(output.status.code(), Some(0), "{}", logs(&output));
    assert_eq!(report(&out)["sensor"], "rgbd");

    let output = run(
        &tum,
        &data.path().join("out-stereo"),
        &["--sensor", "stereo"],
    );
    assert_eq!(output.status.code(), Some(1), "{}", logs(&output));
    assert!(
        logs(&output).contains("needs right images"),
        "{}",
        logs(&output)
    );

    // The slow-machine hook: the threaded mapper 3x slower still tracks
    // the first 20 frames (a straight street); bad factors are refused.
    let out = data.path().join("out-slow");
    let output = run_threaded(
        &synth_dataset,
        &out,
        &["--frames", "20", "--mapping-slowdown", "3"],
    );
    assert_eq!(output.status.code(), Some(0), "{}", logs(&output));
    let r = report(&out);
    assert_eq!(r["mapping"], "thread, 3x slowed", "{}", logs(&output));
    assert_eq!(tracked(&r), 20, "{}", logs(&output));
    let output = run_threaded(
        &synth_dataset,
        &data.path().join("out-slow-bad"),
        &["--mapping-slowdown", "0.5"],
    );
    assert_eq!(output.status.code(), Some(1), "{}", logs(&output));
    assert!(
        logs(&output).contains("at least 1 and at most 100"),
        "{}",
        logs(&output)
    );
    let output = run(
        &synth_dataset,
        &data.path().join("out-slow-inline"),
        &["--mapping-slowdown", "5"],
    );
    assert_eq!(output.status.code(), Some(1), "{}", logs(&output));
    assert!(
        logs(&output).contains("--inline-mapping"),
        "{}",
        logs(&output)
    );

    // A KITTI-layout sequence with the left camera only (like the shared
    // KITTI 07 excerpt) runs as monocular by default; stereo is refused.
    std::fs::remove_dir_all(sequence.join("image_1")).expect("remove image_1");
    let out = data.path().join("out-left-only");
    let output = run(&synth_dataset, &out, &["--frames", "20"]);
    assert_eq!(output.status.code(), Some(0), "{}", logs(&output));
    let r = report(&out);
    assert_eq!(r["sensor"], "mono");
    assert!(tracked(&r) >= 10, "{}", logs(&output));
    let output = run(
        &synth_dataset,
        &data.path().join("out-left-only-stereo"),
        &["--sensor", "stereo"],
    );
    assert_eq!(output.status.code(), Some(1), "{}", logs(&output));
    assert!(logs(&output).contains("no image_1/"), "{}", logs(&output));
}

#[test]
fn bad_depth_images_are_named_and_skipped_or_refused() {
    let data = synth("bad-depth");
    let sequence = data.path().join("sequences/00");
    // An 8-bit image where frame 5's depth should be, a smaller one at 9.
    let gray = sequence.join("image_0/000005.png");
    std::fs::copy(&gray, sequence.join("depth/000005.png")).expect("copy");
    let small = data.path().join("small.png");
    let out = spslam()
        .arg("synth")
        .arg("--out")
        .arg(data.path().join("small"))
        .args(["--frames", "1", "--size", "320x240"])
        .output()
        .expect("run spslam synth");
    assert!(out.status.success());
    std::fs::copy(
        data.path().join("small/sequences/00/depth/000000.png"),
        &small,
    )
    .expect("copy");
    std::fs::copy(&small, sequence.join("depth/000009.png")).expect("copy");
    let out = data.path().join("out");
    let output = run(&format!("tum:{}", sequence.display()), &out, &[]);
    let text = logs(&output);
    assert_eq!(output.status.code(), Some(0), "{text}");
    let r = report(&out);
    let unreadable = r["unreadable_frames"]
        .as_array()
        .cloned()
        .unwrap_or_default();
    let reasons: Vec<String> = unreadable.iter().map(|u| u.to_string()).collect();
    assert_eq!(unreadable.len(), 2, "{reasons:?}");
    assert!(
        reasons[0].contains("depth/000005.png") && reasons[0].contains("8-bit"),
        "{reasons:?}"
    );
    assert!(
        reasons[1].contains("depth/000009.png") && reasons[1].contains("320x240"),
        "{reasons:?}"
    );

    // A wrong DepthMapFactor (1: the PNGs' 5000 units read as metres) is
    // refused before the run starts, naming the file and the key.
    let settings = data.path().join("wrong_factor.yaml");
    std::fs::write(
        &settings,
        "%YAML:1.0\nCamera.fx: 300.0\nCamera.fy: 300.0\nCamera.cx: 239.5\nCamera.cy: 179.5\nCamera.bf: 40.0\nDepthMapFactor: 1.0\n",
    )
    .expect("write settings");
    let output = run(
        &format!("tum:{}", sequence.display()),
        &data.path().join("out-factor"),
        &["--settings", settings.to_str().unwrap_or_default()],
    );
    let text = logs(&output);
    assert_eq!(output.status.code(), Some(1), "{text}");
    assert!(
        text.contains("DepthMapFactor") && text.contains("depth/000000.png"),
        "{text}"
    );
}

#[test]
fn lost_rows_omit_leaves_untracked_frames_out_of_tum_files_and_is_refused_for_kitti() {
    let data = synth("lost-rows");
    let sequence = data.path().join("sequences/00");
    // Frame 5's depth map is an 8-bit image: the frame is unreadable,
    // counted as lost.
    std::fs::copy(
        sequence.join("image_0/000005.png"),
        sequence.join("depth/000005.png"),
    )
    .expect("copy");
    let rows = |out: &Path| -> Vec<f64> {
        let text = std::fs::read_to_string(out.join("trajectory_tum.txt")).expect("trajectory");
        text.lines()
            .filter(|l| !l.starts_with('#'))
            .filter_map(|l| l.split_whitespace().next()?.parse().ok())
            .collect()
    };
    let tum = format!("tum:{}", sequence.display());

    let predicted = data.path().join("predict");
    let output = run(&tum, &predicted, &[]);
    assert_eq!(output.status.code(), Some(0), "{}", logs(&output));
    assert_eq!(rows(&predicted).len(), FRAMES, "a row per frame by default");

    let omitted = data.path().join("omit");
    let output = run(&tum, &omitted, &["--lost-rows", "omit"]);
    assert_eq!(output.status.code(), Some(0), "{}", logs(&output));
    let r = report(&omitted);
    let tracked_stamps: Vec<f64> = r["frames"]
        .as_array()
        .map(|frames| {
            frames
                .iter()
                .filter(|f| f["state"] == "Ok")
                .filter_map(|f| f["timestamp"].as_f64())
                .collect()
        })
        .unwrap_or_default();
    assert!(tracked_stamps.len() < FRAMES, "frame 5 is not tracked");
    let written = rows(&omitted);
    assert_eq!(
        written.len(),
        tracked_stamps.len(),
        "one row per tracked frame"
    );
    for (w, t) in written.iter().zip(&tracked_stamps) {
        assert!((w - t).abs() < 1e-6, "row at {w} s, tracked frame at {t} s");
    }
    assert_eq!(
        r["evaluation"]["matched_poses"].as_u64(),
        Some(written.len() as u64),
        "the evaluation covers the rows written"
    );

    // A KITTI-format trajectory needs every row: refused before the run.
    let output = run(
        &format!("synth:{}", data.path().display()),
        &data.path().join("omit-kitti"),
        &["--lost-rows", "omit"],
    );
    let text = logs(&output);
    assert_eq!(output.status.code(), Some(1), "{text}");
    assert!(
        text.contains("--lost-rows omit") && text.contains("KITTI-format"),
        "{text}"
    );
}

/// SuperPoint's default pyramid is chosen by the sensor and the model
/// (`ExtractorSettings::superpoint_levels_for`): one level with a depth,
/// four without, one without for SuperPoint-Lite; `--levels` overrides it.
#[test]
fn superpoint_levels_default_to_one_with_a_depth_and_four_without() {
    if !common::model_available("superpoint_levels_default_to_one_with_a_depth_and_four_without") {
        return;
    }
    let lite = Precision::Int8.model_path_for(ModelWeights::Lite);
    let lite_available = lite.is_file();
    if !lite_available {
        common::missing(
            "superpoint_levels_default_to_one_with_a_depth_and_four_without (lite's cases)",
            &format!("SuperPoint-Lite's model ({})", lite.display()),
        );
    }
    let data = synth("levels");
    let synth_dataset = format!("synth:{}", data.path().display());
    for (sensor, extra, model, levels) in [
        ("rgbd", None, None, 1),
        ("mono", None, None, 4),
        ("mono", Some("2"), None, 2),
        ("mono", None, Some("lite"), 1),
        ("mono", Some("2"), Some("lite"), 2),
    ] {
        if model == Some("lite") && !lite_available {
            continue;
        }
        let out = data.path().join(format!(
            "out-{sensor}-{levels}-{}",
            model.unwrap_or("default")
        ));
        let mut command = spslam();
        command
            .arg("run")
            .args(["--dataset", &synth_dataset, "--sensor", sensor])
            .args([
                "--extractor",
                "superpoint",
                "--inline-mapping",
                "--frames",
                "2",
            ])
            .arg("--out")
            .arg(&out);
        if let Some(n) = extra {
            command.args(["--levels", n]);
        }
        if let Some(m) = model {
            command.args(["--model", m]);
        }
        let output = command.output().expect("run spslam run");
        assert_eq!(output.status.code(), Some(0), "{}", logs(&output));
        let r = report(&out);
        let inference = r["inference"].as_str().unwrap_or_default();
        assert!(
            inference.ends_with(&format!(", {levels} levels")),
            "{sensor} {extra:?} {model:?}: {inference}"
        );
    }
}
