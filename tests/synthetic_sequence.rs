//! Written synthetic sequences: the KITTI and TUM readers open them, the
//! ground truth reads back through `spslam::eval`, the depth PNGs hold
//! Z·5000, the same seed writes the same bytes, and `spslam synth` works.

use std::path::{Path, PathBuf};
use std::process::Command;

use opencv::imgcodecs::{imread, IMREAD_ANYDEPTH};
use opencv::prelude::*;
use spslam::dataset::synthetic::{
    write_sequence, SceneName, SyntheticConfig, SyntheticError, SyntheticSequence, WriteOptions,
};
use spslam::dataset::{KittiSequence, TumRgbdSequence, DEFAULT_MAX_DIFFERENCE};
use spslam::eval::{read_trajectory, TrajectoryFormat};

/// A fresh, empty folder under the system's temp dir.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("spslam-synth-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn small(scene: SceneName, seed: u64, frames: usize) -> SyntheticConfig {
    let mut config = SyntheticConfig::for_scene(scene);
    config.width = 320;
    config.height = 240;
    config.focal_length = 200.0;
    config.frames = Some(frames);
    config.seed = seed;
    config
}

fn write(config: SyntheticConfig, root: &Path) -> spslam::dataset::synthetic::WrittenSequence {
    let sequence = SyntheticSequence::new(config).unwrap();
    write_sequence(&sequence, root, &WriteOptions::default(), &mut |_, _| {})
        .unwrap_or_else(|e| panic!("{e}"))
}

/// Every file under `dir` with its bytes, sorted by path.
fn contents(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut files = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else {
                let bytes = std::fs::read(&path).unwrap();
                files.push((path.strip_prefix(dir).unwrap().to_path_buf(), bytes));
            }
        }
    }
    files.sort();
    files
}

#[test]
fn the_kitti_reader_opens_it_and_the_ground_truth_matches() {
    let root = scratch("kitti");
    let config = small(SceneName::Wobbly, 3, 5);
    let sequence = SyntheticSequence::new(config.clone()).unwrap();
    let written = write(config, &root);
    let kitti = KittiSequence::open(&root, "00").unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(kitti.frames().len(), 5);
    assert_eq!(kitti.dir(), written.sequence_dir);
    let calib = kitti.calibration();
    assert_eq!(
        (calib.fx, calib.fy, calib.cx, calib.cy),
        (200.0, 200.0, 159.5, 119.5)
    );
    assert!((calib.baseline - 0.12).abs() < 1e-12);
    assert!((kitti.frames()[2].timestamp - 0.1).abs() < 1e-9);

    let gt_path = kitti.ground_truth_path().expect("poses/00.txt is found");
    assert_eq!(gt_path, written.poses_path);
    let gt = read_trajectory(&gt_path, TrajectoryFormat::Kitti).unwrap();
    assert_eq!(gt.len(), 5);
    for (i, pose) in gt.poses.iter().enumerate() {
        let expected = sequence.pose(i);
        let error = (pose.to_homogeneous() - expected.to_homogeneous())
            .abs()
            .max();
        assert!(error < 1e-9, "frame {i}: {error}");
    }
    assert_eq!(gt.poses[0], nalgebra::Isometry3::identity());
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn the_tum_reader_opens_it_and_depth_holds_z_times_5000() {
    let root = scratch("tum");
    let config = small(SceneName::Wobbly, 4, 3).noiseless();
    let sequence = SyntheticSequence::new(config.clone()).unwrap();
    let written = write(config, &root);
    let tum = TumRgbdSequence::open(&written.sequence_dir, DEFAULT_MAX_DIFFERENCE)
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(tum.frames().len(), 3);
    let truth = read_trajectory(
        &tum.ground_truth_path().expect("groundtruth.txt"),
        TrajectoryFormat::Tum,
    )
    .unwrap();
    for (i, pose) in truth.poses.iter().enumerate() {
        let expected = sequence.pose(i);
        assert!((pose.translation.vector - expected.translation.vector).norm() < 1e-8);
        assert!(pose.rotation.angle_to(&expected.rotation) < 1e-8);
    }

    let frame = sequence.render(2, true);
    let path = &tum.frames()[2].depth;
    let png = imread(path.to_str().unwrap(), IMREAD_ANYDEPTH).unwrap();
    assert_eq!(png.typ(), opencv::core::CV_16UC1);
    let mut checked = 0;
    for y in 0..frame.height {
        for x in 0..frame.width {
            let stored = *png.at_2d::<u16>(y as i32, x as i32).unwrap();
            let z = frame.depth[y * frame.width + x] as f64;
            let expected = (z * 5000.0).round();
            if (1.0..=65535.0).contains(&expected) {
                assert_eq!(stored as f64, expected, "({x}, {y})");
                checked += 1;
            } else {
                assert_eq!(
                    stored, 0,
                    "({x}, {y}): no depth beyond 13.1 m or in the sky"
                );
            }
        }
    }
    assert!(checked > frame.width * frame.height / 2, "{checked}");
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn the_same_seed_writes_the_same_bytes_and_another_seed_does_not() {
    let (a, b, c) = (scratch("seed-a"), scratch("seed-b"), scratch("seed-c"));
    write(small(SceneName::Loop, 11, 3), &a);
    write(small(SceneName::Loop, 11, 3), &b);
    write(small(SceneName::Loop, 12, 3), &c);
    let (ca, cb, cc) = (contents(&a), contents(&b), contents(&c));
    assert_eq!(ca.len(), cb.len());
    assert!(ca == cb, "same seed, different bytes");
    let image = |files: &[(PathBuf, Vec<u8>)], name: &str| {
        files
            .iter()
            .find(|(p, _)| p.ends_with(name))
            .map(|(_, bytes)| bytes.clone())
            .unwrap()
    };
    for name in ["image_0/000001.png", "image_1/000001.png"] {
        assert_ne!(image(&ca, name), image(&cc, name), "{name}");
    }
    // The loop's path does not depend on the seed; the world does.
    assert_eq!(image(&ca, "poses/00.txt"), image(&cc, "poses/00.txt"));
    for dir in [a, b, c] {
        std::fs::remove_dir_all(dir).unwrap();
    }
}

#[test]
fn a_filled_folder_is_refused_unless_overwriting() {
    let root = scratch("overwrite");
    write(small(SceneName::Straight, 0, 2), &root);
    let sequence = SyntheticSequence::new(small(SceneName::Straight, 0, 1)).unwrap();
    let error = write_sequence(&sequence, &root, &WriteOptions::default(), &mut |_, _| {})
        .expect_err("the folder is not empty");
    assert!(
        matches!(error, SyntheticError::OutputNotEmpty { .. }),
        "{error}"
    );
    assert!(error.to_string().contains("--overwrite"), "{error}");
    let options = WriteOptions {
        overwrite: true,
        ..WriteOptions::default()
    };
    write_sequence(&sequence, &root, &options, &mut |_, _| {}).unwrap();
    assert_eq!(KittiSequence::open(&root, "00").unwrap().frames().len(), 1);
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn spslam_synth_writes_a_sequence_and_rejects_bad_arguments() {
    let root = scratch("cli");
    let out = Command::new(env!("CARGO_BIN_EXE_spslam"))
        .args([
            "synth", "--scene", "straight", "--frames", "3", "--size", "160x120",
        ])
        .args(["--seed", "5", "--baseline", "0.3", "--no-depth", "--out"])
        .arg(&root)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let kitti = KittiSequence::open(&root, "00").unwrap();
    assert_eq!(kitti.frames().len(), 3);
    assert!((kitti.calibration().baseline - 0.3).abs() < 1e-12);
    assert!(!kitti.dir().join("depth").exists());

    for bad in [
        vec!["--size", "160by120"],
        vec!["--scene", "ring"],
        vec!["--baseline=-1"],
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_spslam"))
            .args(["synth", "--frames", "1", "--out"])
            .arg(root.join("bad"))
            .args(&bad)
            .output()
            .unwrap();
        assert!(!out.status.success(), "{bad:?} accepted");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(
            stderr.contains("WIDTHxHEIGHT")
                || stderr.contains("unknown scene")
                || stderr.contains("baseline"),
            "{bad:?}: {stderr}"
        );
    }
    std::fs::remove_dir_all(&root).unwrap();
}

/// On the loop in its own light the frame count only ends a sequence:
/// frame `i` of a short run, of a long one and of one lap are the same
/// pixels, pose and time. (The tests' frame cache,
/// `common::synthetic_slam::pixel_config`, lets runs of different lengths
/// share their frames on this; the open scenes build a street as long as
/// the run, so their frames differ, as this test also checks.)
#[test]
fn the_frame_count_does_not_change_a_loop_frame_without_a_condition() {
    let mut open = small(SceneName::Straight, 3, 6);
    let open_short = SyntheticSequence::new(open.clone())
        .unwrap()
        .render(0, false);
    open.frames = Some(500);
    let open_long = SyntheticSequence::new(open).unwrap().render(0, false);
    assert_ne!(
        open_short.left, open_long.left,
        "the straight street no longer grows with the run: the cache key may drop its frame count"
    );
    let scene = SceneName::Loop;
    let short = SyntheticSequence::new(small(scene, 3, 6)).unwrap();
    let mut long_config = small(scene, 3, 6);
    long_config.frames = Some(500);
    let long = SyntheticSequence::new(long_config).unwrap();
    let mut lap_config = small(scene, 3, 6);
    lap_config.frames = None;
    let lap = SyntheticSequence::new(lap_config).unwrap();
    for index in [0, 5] {
        let a = short.render(index, false);
        let with_depth = short.render(index, true);
        assert!(
            a.left == with_depth.left
                && a.right == with_depth.right
                && !with_depth.depth.is_empty(),
            "{scene:?} frame {index}: rendering the depth map changes the images"
        );
        for other in [&long, &lap] {
            let b = other.render(index, false);
            assert_eq!(a.timestamp, b.timestamp, "{scene:?} frame {index}");
            assert_eq!(a.pose, b.pose, "{scene:?} frame {index}");
            assert!(
                a.left == b.left && a.right == b.right,
                "{scene:?} frame {index}: the pixels depend on the frame count"
            );
        }
    }
}
