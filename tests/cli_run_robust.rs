//! `spslam run` loses no data: frames that cannot be read are skipped and
//! counted as lost (or, with `--strict`, end the run), and however the run
//! ends (complete, strict stop, SIGTERM) the trajectory and the report of
//! every frame processed are written; the exit code tells complete (0)
//! from incomplete (2) and could-not-start (1).
//!
//! Synthetic data only (`spslam synth`), ORB features (no model needed).

mod common;

use common::temp_dir::TempDir;
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::sync::{Arc, Mutex, Weak};
use std::time::Instant;

/// Frames of the shared sequence (the SIGTERM test needs a long run).
const SEQUENCE_FRAMES: usize = 60;
/// Frames of the damaged copies.
const FRAMES: usize = 20;

fn spslam() -> Command {
    Command::new(env!("CARGO_BIN_EXE_spslam"))
}

/// Writes a synthetic sequence into `root` (KITTI layout, sequence 00).
fn synth(root: &Path, frames: usize, size: &str) {
    let out = spslam()
        .arg("synth")
        .arg("--out")
        .arg(root)
        .args([
            "--frames",
            &frames.to_string(),
            "--size",
            size,
            "--no-depth",
        ])
        .output()
        .expect("run spslam synth");
    assert!(
        out.status.success(),
        "spslam synth failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The synthetic sequence shared by the tests running at the same time;
/// its folder goes when the last of them drops it.
fn shared_sequence() -> Arc<TempDir> {
    static SHARED: Mutex<Weak<TempDir>> = Mutex::new(Weak::new());
    let mut slot = SHARED.lock().unwrap_or_else(|p| p.into_inner());
    if let Some(dir) = slot.upgrade() {
        return dir;
    }
    let start = Instant::now();
    let dir = TempDir::new("run-robust", "sequence");
    synth(dir.path(), SEQUENCE_FRAMES, "480x360");
    eprintln!(
        "synthesised {SEQUENCE_FRAMES} frames in {:.1} s",
        start.elapsed().as_secs_f64()
    );
    let dir = Arc::new(dir);
    *slot = Arc::downgrade(&dir);
    dir
}

/// The first `n` lines of a text file.
fn head(path: &Path, n: usize) -> String {
    let text = std::fs::read_to_string(path).expect("read a text file");
    text.lines().take(n).map(|l| format!("{l}\n")).collect()
}

/// Copies the first `n` frames of the shared sequence (images, times,
/// ground truth) into a new root.
fn copy_frames(n: usize, tag: &str) -> (Arc<TempDir>, TempDir) {
    let source = shared_sequence();
    let from = source.path();
    let copy = TempDir::new("run-robust", tag);
    let (seq_from, seq_to) = (from.join("sequences/00"), copy.path().join("sequences/00"));
    for camera in ["image_0", "image_1"] {
        std::fs::create_dir_all(seq_to.join(camera)).expect("create the image folders");
        for i in 0..n {
            let file = format!("{camera}/{i:06}.png");
            std::fs::copy(seq_from.join(&file), seq_to.join(&file)).expect("copy an image");
        }
    }
    std::fs::copy(seq_from.join("calib.txt"), seq_to.join("calib.txt")).expect("copy calib.txt");
    std::fs::write(
        seq_to.join("times.txt"),
        head(&seq_from.join("times.txt"), n),
    )
    .expect("write times.txt");
    std::fs::create_dir_all(copy.path().join("poses")).expect("create poses/");
    std::fs::write(
        copy.path().join("poses/00.txt"),
        head(&from.join("poses/00.txt"), n),
    )
    .expect("write the ground truth");
    (source, copy)
}

/// `spslam run --extractor orb --inline-mapping` on a synthetic root.
fn run(dataset: &Path, out: &Path, extra: &[&str]) -> Output {
    let start = Instant::now();
    let output = spslam()
        .arg("run")
        .arg("--dataset")
        .arg(format!("synth:{}", dataset.display()))
        .args(["--extractor", "orb", "--inline-mapping", "--out"])
        .arg(out)
        .args(extra)
        .output()
        .expect("run spslam run");
    eprintln!(
        "spslam run {extra:?}: {:.1} s, {}",
        start.elapsed().as_secs_f64(),
        output.status
    );
    output
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

fn trajectory_rows(out: &Path) -> usize {
    std::fs::read_to_string(out.join("trajectory_kitti.txt"))
        .expect("trajectory written")
        .lines()
        .filter(|l| !l.trim().is_empty())
        .count()
}

/// Checks a complete run with exactly one unreadable frame, `index`, whose
/// image is `file`.
fn assert_one_skipped(output: &Output, out: &Path, index: usize, file: &str) {
    let logs = logs(output);
    assert_eq!(output.status.code(), Some(0), "{logs}");
    assert_eq!(trajectory_rows(out), FRAMES, "{logs}");
    let r = report(out);
    assert_eq!(r["complete"], true, "{logs}");
    assert_eq!(r["end"], "complete");
    assert_eq!(r["frames_total"], FRAMES);
    assert_eq!(r["frames_processed"], FRAMES);
    let unreadable = r["unreadable_frames"].as_array().expect("a list");
    assert_eq!(unreadable.len(), 1, "{unreadable:?}");
    assert_eq!(unreadable[0]["index"], index);
    let path = unreadable[0]["path"].as_str().expect("a path");
    assert!(path.ends_with(file), "{path} does not name {file}");
    let s = &r["summary"];
    assert_eq!(s["unreadable"], 1);
    assert!(s["lost"].as_u64().expect("lost") >= 1);
    assert_eq!(s["tracked"], FRAMES - 1, "{s}");
    assert!(
        r["frames"][index]["unreadable"].is_string(),
        "frame {index}'s record says why"
    );
    // The warning names the frame and the file.
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains(&format!("frame {index} skipped")) && stderr.contains(file),
        "{stderr}"
    );
    let text = std::fs::read_to_string(out.join("report.txt")).expect("report.txt written");
    assert!(text.starts_with("run complete"), "{text}");
    assert!(
        text.contains(&format!("unreadable frame {index}")),
        "{text}"
    );
    assert!(text.contains("map 0: first frame 0"), "{text}");
}

/// Overwrites frame 15's left image with bytes that are not a PNG.
fn corrupt_frame_15(root: &Path) {
    let garbage: Vec<u8> = (0..4096u32).map(|i| (i * 7919 % 251) as u8).collect();
    std::fs::write(root.join("sequences/00/image_0/000015.png"), garbage)
        .expect("overwrite an image");
}

#[test]
fn corrupt_frame_is_skipped_and_the_run_is_complete() {
    let (_shared, data) = copy_frames(FRAMES, "corrupt");
    corrupt_frame_15(data.path());
    let out = TempDir::new("run-robust", "corrupt-out");
    let output = run(data.path(), out.path(), &[]);
    assert_one_skipped(&output, out.path(), 15, "image_0/000015.png");
}

#[test]
fn strict_stops_at_the_corrupt_frame_and_writes_the_frames_before() {
    let (_shared, data) = copy_frames(FRAMES, "strict");
    corrupt_frame_15(data.path());
    let out = TempDir::new("run-robust", "strict-out");
    let map = out.path().join("early.spmap");
    let map_arg = map.display().to_string();
    let output = run(
        data.path(),
        out.path(),
        &["--strict", "--save-map", &map_arg],
    );
    let logs = logs(&output);
    assert_eq!(output.status.code(), Some(2), "{logs}");
    // The run ended early, and its map was saved all the same.
    let info = spslam()
        .args(["map", "info"])
        .arg(&map)
        .output()
        .expect("run spslam map info");
    let info_text = String::from_utf8_lossy(&info.stdout);
    assert!(
        info.status.success(),
        "{info_text}{}",
        String::from_utf8_lossy(&info.stderr)
    );
    assert!(
        info_text.contains("format version 3")
            && info_text.contains("extractor orb")
            && info_text.contains("camera: stereo"),
        "{info_text}"
    );
    let loaded = spslam::storage::load(&map).unwrap_or_else(|e| panic!("{e}"));
    let keyframes: usize = loaded.maps.iter().map(|m| m.map.keyframe_count()).sum();
    assert!(keyframes > 0, "{info_text}");
    assert!(
        loaded
            .maps
            .iter()
            .flat_map(|m| m.map.keyframes())
            .all(|k| k.frame_index < 15),
        "keyframes from frames after the stop"
    );
    assert_eq!(trajectory_rows(out.path()), 15, "{logs}");
    assert!(out.path().join("keyframes_tum.txt").is_file());
    let r = report(out.path());
    assert_eq!(r["complete"], false);
    assert_eq!(r["frames_total"], FRAMES);
    assert_eq!(r["frames_processed"], 15);
    let end = r["end"].as_str().expect("end");
    assert!(
        end.starts_with("failed:") && end.contains("frame 15") && end.contains("000015.png"),
        "{end}"
    );
    let text = std::fs::read_to_string(out.path().join("report.txt")).expect("report.txt");
    assert!(text.starts_with("run INCOMPLETE"), "{text}");
}

#[test]
fn missing_right_image_is_skipped_and_counted_as_lost() {
    let (_shared, data) = copy_frames(FRAMES, "missing");
    std::fs::remove_file(data.path().join("sequences/00/image_1/000007.png"))
        .expect("remove an image");
    let out = TempDir::new("run-robust", "missing-out");
    let output = run(data.path(), out.path(), &[]);
    assert_one_skipped(&output, out.path(), 7, "image_1/000007.png");
    let r = report(out.path());
    assert_eq!(r["unreadable_frames"][0]["reason"], "no such file");
}

#[test]
fn image_of_another_size_is_skipped() {
    let (_shared, data) = copy_frames(FRAMES, "resized");
    let small = TempDir::new("run-robust", "small");
    synth(small.path(), 2, "240x180");
    std::fs::copy(
        small.path().join("sequences/00/image_0/000001.png"),
        data.path().join("sequences/00/image_0/000004.png"),
    )
    .expect("replace an image");
    let out = TempDir::new("run-robust", "resized-out");
    let output = run(data.path(), out.path(), &[]);
    assert_one_skipped(&output, out.path(), 4, "image_0/000004.png");
    let reason = report(out.path())["unreadable_frames"][0]["reason"].clone();
    assert!(
        reason.as_str().is_some_and(|r| r.contains("240x180")),
        "{reason}"
    );
}

#[test]
fn sigterm_writes_the_frames_processed_so_far() {
    let data = shared_sequence();
    let out = TempDir::new("run-robust", "sigterm-out");
    let start = Instant::now();
    // The debug log marks each frame done, so that the signal comes after
    // the first frame and long before the last (60 frames, ~1-3 s).
    let mut child = spslam()
        .arg("run")
        .arg("--dataset")
        .arg(format!("synth:{}", data.path().display()))
        .args(["--extractor", "orb", "--out"])
        .arg(out.path())
        .env("RUST_LOG", "warn,spslam::run=debug")
        .env("NO_COLOR", "1")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start spslam run");
    let stderr = child.stderr.take().expect("stderr is piped");
    let mut lines = BufReader::new(stderr).lines();
    let mut seen = Vec::new();
    let mut signalled = false;
    for line in lines.by_ref() {
        let line = line.expect("read stderr");
        let done = line.contains("frame processed");
        seen.push(line);
        if done {
            let status = Command::new("kill")
                .args(["-TERM", &child.id().to_string()])
                .status()
                .expect("run kill");
            assert!(status.success(), "kill -TERM failed");
            signalled = true;
            break;
        }
    }
    // Drain the rest so that the child never blocks on a full pipe.
    seen.extend(lines.map_while(Result::ok));
    let status = child.wait().expect("wait for spslam run");
    let seen = seen.join("\n");
    eprintln!(
        "SIGTERM run: {:.1} s, {status}",
        start.elapsed().as_secs_f64()
    );
    assert!(signalled, "no frame was processed:\n{seen}");
    assert_eq!(status.code(), Some(2), "{seen}");
    let r = report(out.path());
    assert_eq!(r["complete"], false, "{seen}");
    assert_eq!(r["end"], "interrupted");
    assert_eq!(r["signal"], "SIGTERM");
    assert_eq!(r["frames_total"], SEQUENCE_FRAMES);
    let processed = r["frames_processed"].as_u64().expect("frames_processed") as usize;
    eprintln!("SIGTERM run: stopped after {processed} of {SEQUENCE_FRAMES} frames");
    assert!(
        (1..SEQUENCE_FRAMES).contains(&processed),
        "{processed} frames"
    );
    assert_eq!(trajectory_rows(out.path()), processed);
    assert_eq!(r["frames"].as_array().map(Vec::len), Some(processed));
    let text = std::fs::read_to_string(out.path().join("report.txt")).expect("report.txt");
    assert!(
        text.starts_with("run INCOMPLETE (interrupted by SIGTERM)"),
        "{text}"
    );
}

#[test]
fn a_dataset_that_cannot_be_opened_exits_with_1() {
    let out = TempDir::new("run-robust", "none-out");
    let missing = out.path().join("no-such-dataset");
    let output = run(&missing, &out.path().join("out"), &[]);
    assert_eq!(output.status.code(), Some(1), "{}", logs(&output));
    assert!(!out.path().join("out/report.json").exists());
    let bad = spslam()
        .args(["run", "--no-such-flag"])
        .output()
        .expect("run spslam");
    assert_eq!(bad.status.code(), Some(1), "{}", logs(&bad));
}

#[test]
fn help_documents_the_exit_codes() {
    let output = spslam()
        .args(["run", "--help"])
        .output()
        .expect("run spslam");
    assert!(output.status.success());
    let help = String::from_utf8_lossy(&output.stdout);
    for needle in ["Exit codes:", "  0  ", "  1  ", "  2  ", "--strict"] {
        assert!(help.contains(needle), "{needle} missing from\n{help}");
    }
}

#[test]
fn memory_log_has_a_row_per_interval_with_the_heap_split() {
    let (_shared, data) = copy_frames(FRAMES, "memory-log");
    let out = TempDir::new("run-robust", "memory-log-out");
    let csv = out.path().join("memory.csv");
    let csv_arg = csv.display().to_string();
    let output = run(
        data.path(),
        out.path(),
        &["--memory-log", &csv_arg, "--memory-every", "5"],
    );
    assert!(output.status.success(), "{}", logs(&output));
    let text = std::fs::read_to_string(&csv).expect("memory.csv written");
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some(
            "frame,rss_mib,heap_in_use_mib,heap_free_held_mib,global_ba_running,\
             keyframes,map_points,maps,heap_release_ms"
        )
    );
    let rows: Vec<Vec<f64>> = lines
        .map(|l| {
            l.split(',')
                .map(|v| v.parse().expect("a number in memory.csv"))
                .collect()
        })
        .collect();
    // One row after each 5 frames of 20.
    let frames: Vec<f64> = rows.iter().map(|r| r[0]).collect();
    assert_eq!(frames, [5.0, 10.0, 15.0, 20.0]);
    for row in &rows {
        let [_, rss, in_use, free_held, global_ba, keyframes, points, maps, release_ms] = row[..]
        else {
            panic!("a row of 9 columns, got {row:?}");
        };
        // The process holds the ORB extractor, images and a map: tens of
        // MiB resident, most of it the allocator's live heap.
        assert!(rss > 10.0, "RSS {rss} MiB");
        if cfg!(all(target_os = "linux", target_env = "gnu")) {
            assert!(
                in_use > 1.0 && in_use < 4.0 * rss,
                "heap in use {in_use} MiB, RSS {rss}"
            );
            assert!(free_held >= 0.0, "freed heap {free_held} MiB");
        }
        assert!(
            global_ba == 0.0 || global_ba == 1.0,
            "global_ba_running {global_ba}"
        );
        // The hand-back runs every 100 frames and after a global BA:
        // neither in 20 frames.
        assert_eq!(release_ms, 0.0);
        assert!(
            keyframes >= 1.0 && points >= 100.0 && maps == 1.0,
            "{row:?}"
        );
    }
    assert!(
        out.path().join("memory.png").is_file(),
        "the plot next to the CSV"
    );
}
