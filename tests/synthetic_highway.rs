//! The `highway` synthetic scene: an open road at 25 m/s whose texture is
//! mostly far away (ORB-SLAM3's stereo "far" points, beyond 40 baselines =
//! 20 m), with a few near objects and no street canyon. Frames are
//! rendered in memory at 480×360 (f = 300 px: the default 77° field of
//! view) without noise; every measured value is printed (`--nocapture`).

use std::process::Command;

use opencv::core::{KeyPoint, Mat, Vector};
use opencv::prelude::*;
use spslam::dataset::synthetic::{SceneName, SyntheticConfig, SyntheticFrame, SyntheticSequence};

/// Frames checked: the start, the middle and the last default frame.
const FRAMES: [usize; 3] = [0, 150, 299];
/// ORB-SLAM3's far-point threshold for the scene's 0.5 m baseline is
/// 40 × 0.5 = 20 m; "far" here is half again as far.
const FAR: f32 = 30.0;
/// Nearer than ORB-SLAM3's close-point threshold.
const NEAR: f32 = 20.0;

/// The highway at 480×360 with the default field of view, noiseless.
fn small() -> SyntheticConfig {
    let mut config = SyntheticConfig::for_scene(SceneName::Highway).noiseless();
    config.width = 480;
    config.height = 360;
    config.focal_length = 300.0;
    config
}

/// The median of `values` (which must not be empty).
fn median(mut values: Vec<f32>) -> f32 {
    assert!(!values.is_empty());
    let middle = values.len() / 2;
    *values.select_nth_unstable_by(middle, f32::total_cmp).1
}

/// The depths of the rows above the image's centre row (0 = sky).
fn upper_depths(frame: &SyntheticFrame) -> &[f32] {
    &frame.depth[..frame.width * (frame.height / 2)]
}

#[test]
fn the_highway_is_long_and_fast() {
    let sequence = SyntheticSequence::new(SyntheticConfig::for_scene(SceneName::Highway)).unwrap();
    let config = sequence.config();
    println!(
        "highway: {} frames, {} m/s at {} fps, baseline {} m, {} planes",
        sequence.len(),
        config.speed,
        config.fps,
        config.baseline,
        sequence.world().planes.len()
    );
    assert!(sequence.len() >= 300, "{} frames", sequence.len());
    assert_eq!(
        (config.speed, config.fps, config.baseline),
        (25.0, 10.0, 0.5)
    );
    assert!(sequence.world().planes.len() < 60);
    let length: f64 = (1..300)
        .map(|i| {
            (sequence.pose(i).translation.vector - sequence.pose(i - 1).translation.vector).norm()
        })
        .sum();
    println!("ground-truth path over 300 frames: {length:.1} m");
    assert!(length >= 600.0, "{length} m");
    assert!((length - 299.0 * 2.5).abs() < 1e-6, "{length} m");
    // The poses keep the conventions: the identity first, heading +z.
    let first = sequence.pose(0).to_homogeneous() - nalgebra::Matrix4::identity();
    assert!(first.norm() < 1e-15, "{first}");
    let last = sequence.pose(299).translation.vector;
    assert!(
        last.x.abs() < 1e-9 && last.y.abs() < 1e-9 && last.z > 700.0,
        "{last}"
    );
}

#[test]
fn most_textured_pixels_are_far_and_some_are_near() {
    let sequence = SyntheticSequence::new(small()).unwrap();
    for index in FRAMES {
        let frame = sequence.render(index, true);
        let upper = upper_depths(&frame);
        let textured: Vec<f32> = upper.iter().copied().filter(|&z| z > 0.0).collect();
        let covered = textured.len() as f64 / upper.len() as f64;
        let upper_median = median(textured.clone());
        let far_share =
            textured.iter().filter(|&&z| z > FAR).count() as f64 / textured.len() as f64;
        let all: Vec<f32> = frame.depth.iter().copied().filter(|&z| z > 0.0).collect();
        let near = all.iter().filter(|&&z| z < NEAR).count() as f64 / all.len() as f64;
        println!(
            "frame {index}: upper half {:.0}% textured, median depth {upper_median:.1} m, \
             {:.1}% beyond {FAR} m; all pixels: median {:.1} m, {:.1}% nearer than {NEAR} m",
            100.0 * covered,
            100.0 * far_share,
            median(all.clone()),
            100.0 * near
        );
        // Far texture fills much of the image above the horizon…
        assert!(covered > 0.4, "frame {index}: {covered}");
        assert!(upper_median > 50.0, "frame {index}: {upper_median} m");
        assert!(far_share > 0.85, "frame {index}: {far_share}");
        // …while the road below it is near.
        assert!(near > 0.3, "frame {index}: {near}");
    }
}

#[test]
fn a_few_near_objects_pass_by_and_no_canyon() {
    // Tiny frames every 5 frames along the drive: how much of the upper
    // half is nearer than 20 m (signs, barriers, cabinets; never walls).
    let mut config = small();
    (config.width, config.height, config.focal_length) = (160, 120, 100.0);
    let sequence = SyntheticSequence::new(config).unwrap();
    let shares: Vec<f64> = (0..300)
        .step_by(5)
        .map(|index| {
            let frame = sequence.render(index, true);
            let upper = upper_depths(&frame);
            let near = upper.iter().filter(|&&z| z > 0.0 && z < NEAR).count();
            near as f64 / upper.len() as f64
        })
        .collect();
    let with_near = shares.iter().filter(|&&s| s > 0.0).count();
    let most = shares.iter().copied().fold(0.0, f64::max);
    let mean = shares.iter().sum::<f64>() / shares.len() as f64;
    println!(
        "near objects above the horizon in {with_near}/{} frames; \
         at most {:.2}% of the upper half, {:.3}% on average",
        shares.len(),
        100.0 * most,
        100.0 * mean
    );
    assert!(with_near >= 6, "{with_near} frames with a near object");
    assert!(most < 0.1, "{most}: a wall near the car?");
    assert!(mean < 0.01, "{mean}");
}

#[test]
fn the_far_texture_is_rich() {
    let sequence = SyntheticSequence::new(small()).unwrap();
    for index in FRAMES {
        let frame = sequence.render(index, true);
        let (width, height) = (frame.width, frame.height);
        let upper = &frame.left[..width * (height / 2)];
        let mean = upper.iter().map(|&g| g as f64).sum::<f64>() / upper.len() as f64;
        let spread = (upper
            .iter()
            .map(|&g| (g as f64 - mean).powi(2))
            .sum::<f64>()
            / upper.len() as f64)
            .sqrt();
        // Central differences: |∂x| + |∂y| of at least 40 gray levels.
        let gray = |x: usize, y: usize| frame.left[y * width + x] as i32;
        let mut strong_far = 0usize;
        for y in 1..height - 1 {
            for x in 1..width - 1 {
                let gradient = (gray(x + 1, y) - gray(x - 1, y)).abs()
                    + (gray(x, y + 1) - gray(x, y - 1)).abs();
                if gradient >= 40 && frame.depth[y * width + x] > FAR {
                    strong_far += 1;
                }
            }
        }
        // FAST corners (OpenCV, threshold 20) on far surfaces.
        let image = Mat::from_slice(&frame.left)
            .unwrap()
            .reshape(1, height as i32)
            .unwrap()
            .try_clone()
            .unwrap();
        let mut corners = Vector::<KeyPoint>::new();
        opencv::features2d::fast(&image, &mut corners, 20, true).unwrap();
        let far_corners = corners
            .iter()
            .filter(|k| {
                let (x, y) = (k.pt().x.round() as usize, k.pt().y.round() as usize);
                frame.depth[y.min(height - 1) * width + x.min(width - 1)] > FAR
            })
            .count();
        println!(
            "frame {index}: upper-half gray spread {spread:.1}; {strong_far} strong-gradient \
             pixels beyond {FAR} m; FAST: {far_corners} of {} corners beyond {FAR} m",
            corners.len()
        );
        assert!(spread > 20.0, "frame {index}: {spread}");
        assert!(strong_far > 5000, "frame {index}: {strong_far}");
        assert!(far_corners > 300, "frame {index}: {far_corners}");
        // Most of the texture is far: so are most corners, road included.
        assert!(
            far_corners * 3 > corners.len() * 2,
            "frame {index}: {far_corners} of {}",
            corners.len()
        );
    }
}

#[test]
fn the_highway_is_deterministic_and_seeded() {
    let mut config = small();
    (config.width, config.height, config.focal_length) = (96, 72, 60.0);
    let a = SyntheticSequence::new(config.clone())
        .unwrap()
        .render(40, true);
    assert_eq!(
        a,
        SyntheticSequence::new(config.clone())
            .unwrap()
            .render(40, true)
    );
    config.seed = 1;
    let b = SyntheticSequence::new(config).unwrap().render(40, true);
    assert_eq!(a.pose, b.pose);
    assert_ne!(a.left, b.left);
}

#[test]
fn spslam_synth_knows_the_highway() {
    let help = Command::new(env!("CARGO_BIN_EXE_spslam"))
        .args(["synth", "--help"])
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&help.stdout).contains("highway"));
    let root = std::env::temp_dir().join(format!("spslam-synth-highway-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&root);
    let out = Command::new(env!("CARGO_BIN_EXE_spslam"))
        .args([
            "synth", "--scene", "highway", "--frames", "2", "--size", "96x72",
        ])
        .args(["--no-depth", "--out"])
        .arg(&root)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let poses = std::fs::read_to_string(root.join("poses/00.txt")).unwrap();
    let second: Vec<f64> = poses
        .lines()
        .nth(1)
        .unwrap()
        .split_whitespace()
        .map(|v| v.parse().unwrap())
        .collect();
    // KITTI rows: [R | t]; the second frame is 2.5 m ahead.
    assert!((second[11] - 2.5).abs() < 1e-9, "{second:?}");
    std::fs::remove_dir_all(&root).unwrap();
}
