//! The `aliasing` synthetic scene: a straight street that passes two
//! look-alike places, A and B (the same façade textures at the same
//! coordinates along the street), whose walls stand at different distances
//! from the road. Images at A and B must look alike (many ORB matches)
//! while their depth differs, and the ordinary street between them must
//! not look like A. Frames are rendered in memory at 480×360 (f = 300 px:
//! the default 77° field of view) without noise; every measured value is
//! printed (`--nocapture`).

use std::process::Command;

use opencv::core::{DMatch, KeyPoint, Mat, Vector, NORM_HAMMING};
use opencv::features2d::{BFMatcher, ORB_ScoreType, ORB};
use opencv::prelude::*;
use spslam::dataset::synthetic::{
    AliasingLayout, SceneName, SyntheticConfig, SyntheticFrame, SyntheticSequence, ALIASING_LAYOUT,
};

/// Lowe's ratio for a "good" descriptor match.
const RATIO: f32 = 0.75;

/// The aliasing street at 480×360 with the default field of view, noiseless.
fn small() -> SyntheticConfig {
    let mut config = SyntheticConfig::for_scene(SceneName::Aliasing).noiseless();
    config.width = 480;
    config.height = 360;
    config.focal_length = 300.0;
    config
}

/// The left image as an OpenCV matrix.
fn left_image(frame: &SyntheticFrame) -> Mat {
    Mat::from_slice(&frame.left)
        .unwrap()
        .reshape(1, frame.height as i32)
        .unwrap()
        .try_clone()
        .unwrap()
}

/// ORB (1000 features, ORB-SLAM's Harris score) on the left image.
fn orb(frame: &SyntheticFrame) -> (Vector<KeyPoint>, Mat) {
    let mut orb = ORB::create(1000, 1.2, 8, 31, 0, 2, ORB_ScoreType::HARRIS_SCORE, 31, 20).unwrap();
    let mut keypoints = Vector::<KeyPoint>::new();
    let mut descriptors = Mat::default();
    orb.detect_and_compute_def(
        &left_image(frame),
        &Mat::default(),
        &mut keypoints,
        &mut descriptors,
    )
    .unwrap();
    assert!(keypoints.len() > 500, "{} ORB keypoints", keypoints.len());
    (keypoints, descriptors)
}

/// The keypoint pairs `(in a, in b)` whose descriptor's nearest neighbour
/// in `b` passes Lowe's ratio test.
fn good_matches(
    (a_points, a): &(Vector<KeyPoint>, Mat),
    (b_points, b): &(Vector<KeyPoint>, Mat),
) -> Vec<(KeyPoint, KeyPoint)> {
    let matcher = BFMatcher::create(NORM_HAMMING, false).unwrap();
    let mut pairs = Vector::<Vector<DMatch>>::new();
    matcher.knn_train_match_def(a, b, &mut pairs, 2).unwrap();
    pairs
        .iter()
        .filter(|pair| {
            pair.len() == 2 && pair.get(0).unwrap().distance < RATIO * pair.get(1).unwrap().distance
        })
        .map(|pair| {
            let best = pair.get(0).unwrap();
            (
                a_points.get(best.query_idx as usize).unwrap(),
                b_points.get(best.train_idx as usize).unwrap(),
            )
        })
        .collect()
}

/// The median of the textured depths (0 = sky) in the left or right half.
fn half_median_depth(frame: &SyntheticFrame, left: bool) -> f32 {
    let width = frame.width;
    let mut depths: Vec<f32> = frame
        .depth
        .iter()
        .enumerate()
        .filter(|&(i, &z)| z > 0.0 && ((i % width) < width / 2) == left)
        .map(|(_, &z)| z)
        .collect();
    assert!(!depths.is_empty());
    let middle = depths.len() / 2;
    *depths.select_nth_unstable_by(middle, f32::total_cmp).1
}

#[test]
fn the_street_passes_place_a_then_place_b_then_more_street() {
    let sequence = SyntheticSequence::new(SyntheticConfig::for_scene(SceneName::Aliasing)).unwrap();
    let config = sequence.config();
    let layout = ALIASING_LAYOUT;
    let step = sequence.trajectory().step;
    let [a_first, a_last] = AliasingLayout::frames_in(layout.place_a, step);
    let [b_first, b_last] = AliasingLayout::frames_in(layout.place_b, step);
    println!(
        "aliasing: {} frames at {} m/s and {} fps ({step} m a frame), {} planes; \
         place A z = {:?} m (frames {a_first}-{a_last}), walls {:?} m; \
         place B z = {:?} m (frames {b_first}-{b_last}), walls {:?} m; street walls {:?} m",
        sequence.len(),
        config.speed,
        config.fps,
        sequence.world().planes.len(),
        layout.place_a,
        layout.walls_a,
        layout.place_b,
        layout.walls_b,
        layout.street_walls,
    );
    assert_eq!(sequence.len(), 300);
    assert_eq!((config.speed, config.fps), (10.0, 10.0));
    // A, then at least 40 m of ordinary street, then B, then more street.
    assert!(a_first > 30 && a_last < b_first && b_first - a_last >= 40);
    assert!(b_last + 50 < sequence.len(), "{b_last}");
    // Straight ahead along +z, 1 m a frame, without turning.
    for i in 0..sequence.len() {
        let pose = sequence.pose(i);
        let t = pose.translation.vector;
        assert!(t.x.abs() < 1e-12 && t.y.abs() < 1e-12 && (t.z - i as f64).abs() < 1e-9);
        assert!(pose.rotation.angle() < 1e-12);
    }
}

#[test]
fn place_b_looks_like_place_a_at_another_depth() {
    let sequence = SyntheticSequence::new(small()).unwrap();
    let layout = ALIASING_LAYOUT;
    let step = sequence.trajectory().step;
    let [a_first, a_last] = AliasingLayout::frames_in(layout.place_a, step);
    let [b_first, _] = AliasingLayout::frames_in(layout.place_b, step);
    // Ordinary street, half-way between the two places.
    let between_index = (a_last + b_first) / 2;
    let between = sequence.render(between_index, true);
    let between_features = orb(&between);
    let width = between.width as f32;
    // At the start of place A and in its middle, and the same frames of B.
    let middle = (a_last - a_first) / 2;
    for offset in [0, middle] {
        let (a_index, b_index) = (a_first + offset, b_first + offset);
        let a = sequence.render(a_index, true);
        let b = sequence.render(b_index, true);
        let (a_features, b_features) = (orb(&a), orb(&b));
        let pairs = good_matches(&a_features, &b_features);
        let a_b = pairs.len();
        let a_between = good_matches(&a_features, &between_features).len();
        let b_between = good_matches(&b_features, &between_features).len();
        // Where the A-B matches lie: on the left or right wall, and on the
        // same image row (every true A-B pair does: the walls only moved
        // sideways, so one epipolar geometry, a sideways translation's,
        // explains both walls and a fundamental-matrix check can't reject).
        let on_left = pairs
            .iter()
            .filter(|(p, q)| p.pt().x < width / 2.0 && q.pt().x < width / 2.0)
            .count();
        let on_right = pairs
            .iter()
            .filter(|(p, q)| p.pt().x >= width / 2.0 && q.pt().x >= width / 2.0)
            .count();
        let same_row = pairs
            .iter()
            .filter(|(p, q)| (p.pt().y - q.pt().y).abs() <= 2.0)
            .count();
        let depth_a = [half_median_depth(&a, true), half_median_depth(&a, false)];
        let depth_b = [half_median_depth(&b, true), half_median_depth(&b, false)];
        println!(
            "{offset} m into the places (frames {a_index} / {b_index}, street frame \
             {between_index}): good ORB matches A-B {a_b} ({on_left} left, {on_right} right, \
             {same_row} on the same row), A-street {a_between}, B-street {b_between}; \
             median depth of the left half A {:.2} m, B {:.2} m, right half A {:.2} m, B {:.2} m",
            depth_a[0], depth_b[0], depth_a[1], depth_b[1]
        );
        // The same texture: many more good matches than with the street.
        assert!(a_b >= 25, "{offset} m: {a_b} good A-B matches");
        assert!(
            a_b >= 3 * a_between.max(1),
            "{offset} m: A-B {a_b}, A-street {a_between}"
        );
        assert!(
            a_b >= 3 * b_between.max(1),
            "{offset} m: A-B {a_b}, B-street {b_between}"
        );
        // Not the same structure: the walls stand farther from B's road.
        for (side, (za, zb)) in ["left", "right"].iter().zip(depth_a.iter().zip(&depth_b)) {
            assert!(zb - za > 2.0, "{offset} m, {side} half: A {za} m, B {zb} m");
        }
    }
}

#[test]
fn spslam_synth_writes_the_aliasing_street() {
    let help = Command::new(env!("CARGO_BIN_EXE_spslam"))
        .args(["synth", "--help"])
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&help.stdout).contains("aliasing"));
    let root = std::env::temp_dir().join(format!("spslam-synth-aliasing-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&root);
    let out = Command::new(env!("CARGO_BIN_EXE_spslam"))
        .args([
            "synth", "--scene", "aliasing", "--frames", "2", "--size", "96x72",
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
    // KITTI rows: [R | t]; the second frame is 1 m ahead.
    assert!((second[11] - 1.0).abs() < 1e-9, "{second:?}");
    let written = std::fs::read_to_string(root.join("sequences/00/synthetic.json")).unwrap();
    assert!(written.contains("\"aliasing\""), "{written}");
    assert!(root.join("sequences/00/image_0/000001.png").is_file());
    std::fs::remove_dir_all(&root).unwrap();
}
