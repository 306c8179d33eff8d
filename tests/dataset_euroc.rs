//! EuRoC reader and stereo rectification on the real V1_01_easy excerpt.

mod common;

use std::path::{Path, PathBuf};

use opencv::calib3d::{find_fundamental_mat, FM_RANSAC};
use opencv::core::{DMatch, KeyPoint, Mat, Point2f, Vector, NORM_HAMMING};
use opencv::features2d::{BFMatcher, ORB_ScoreType, ORB};
use opencv::imgcodecs::{imread, IMREAD_GRAYSCALE};
use opencv::prelude::*;
use spslam::dataset::{CameraCalibration, EurocSequence, StereoRectifier};

fn euroc_dir(test: &str) -> Option<PathBuf> {
    let data = common::data_dir(test)?;
    let dir = data.join("euroc/V1_01_easy_first95");
    if dir.join("mav0/cam0/data.csv").is_file() {
        Some(dir)
    } else {
        common::missing(test, &format!("the EuRoC excerpt ({})", dir.display()));
        None
    }
}

fn assert_camera(c: &CameraCalibration, k: [f64; 4], d: [f64; 4]) {
    assert_eq!((c.width, c.height), (752, 480));
    assert_eq!([c.fx, c.fy, c.cx, c.cy], k);
    assert_eq!(c.distortion, d);
    assert_eq!(c.t_bs[(3, 3)], 1.0);
}

#[test]
fn euroc_pairs_calibration_and_imu() {
    let Some(dir) = euroc_dir("euroc_pairs_calibration_and_imu") else {
        return;
    };
    let seq = EurocSequence::open(&dir).expect("open EuRoC");
    assert_eq!(seq.frames().len(), 95);
    assert!(seq.unmatched_left().is_empty() && seq.unmatched_right().is_empty());
    assert_eq!(seq.frame_timestamps_ns()[0], 1_403_715_273_262_142_976);
    assert!((seq.frames()[0].timestamp - 1_403_715_273.262_143).abs() < 1e-6);
    assert!(seq
        .frames()
        .windows(2)
        .all(|w| w[0].timestamp < w[1].timestamp));

    assert_camera(
        seq.cam0(),
        [458.654, 457.296, 367.215, 248.375],
        [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05],
    );
    assert_camera(
        seq.cam1(),
        [457.587, 456.134, 379.999, 255.238],
        [-0.28368365, 0.07451284, -0.00010473, -3.55590700e-05],
    );
    assert_eq!(seq.cam0().t_bs[(0, 1)], -0.999880929698);
    assert_eq!(seq.cam1().t_bs[(1, 3)], 0.0453689425024);

    let imu = seq.imu();
    assert_eq!(imu.len(), 29120);
    assert!(imu.windows(2).all(|w| w[0].t < w[1].t));
    assert!((imu[0].accel.x - 9.087_495_666_666_666).abs() < 1e-12);

    let gt = seq.ground_truth_path().expect("ground truth csv");
    assert!(gt.ends_with("state_groundtruth_estimate0/data.csv"));

    // The mav0 folder itself opens too.
    let same = EurocSequence::open(dir.join("mav0")).expect("open mav0");
    assert_eq!(same.frames(), seq.frames());
}

fn gray(path: &Path) -> Mat {
    let m = imread(path, IMREAD_GRAYSCALE).expect("imread");
    assert!(!m.empty(), "cannot decode {}", path.display());
    m
}

/// Row alignment of ORB matches between two images.
struct RowAlignment {
    /// Cross-checked matches.
    matches: usize,
    /// Fraction of all cross-checked matches within 2 px of the same row.
    all: f64,
    /// Matches consistent with a RANSAC fundamental matrix (1 px).
    inliers: usize,
    /// Fraction of those inliers within 2 px of the same row.
    inlier: f64,
}

/// ORB (1000) on both images, brute-force Hamming with cross-check; the
/// fraction of matches within 2 px of the same row, over all matches and
/// over the epipolar-consistent ones (RANSAC F, which does not assume
/// rectified images, so it removes wrong matches without favouring rows).
fn row_alignment(left: &Mat, right: &Mat) -> RowAlignment {
    let mut orb =
        ORB::create(1000, 1.2, 8, 31, 0, 2, ORB_ScoreType::HARRIS_SCORE, 31, 20).expect("ORB");
    let detect = |orb: &mut opencv::core::Ptr<ORB>, img: &Mat| {
        let mut kps = Vector::<KeyPoint>::new();
        let mut desc = Mat::default();
        orb.detect_and_compute_def(img, &Mat::default(), &mut kps, &mut desc)
            .expect("detect");
        (kps, desc)
    };
    let (kl, dl) = detect(&mut orb, left);
    let (kr, dr) = detect(&mut orb, right);
    let matcher = BFMatcher::create(NORM_HAMMING, true).expect("matcher");
    let mut matches = Vector::<DMatch>::new();
    matcher
        .train_match_def(&dl, &dr, &mut matches)
        .expect("match");
    let n = matches.len();
    assert!(n >= 50, "only {n} ORB matches");
    let mut pl = Vector::<Point2f>::new();
    let mut pr = Vector::<Point2f>::new();
    for m in matches.iter() {
        pl.push(kl.get(m.query_idx as usize).expect("kp").pt());
        pr.push(kr.get(m.train_idx as usize).expect("kp").pt());
    }
    let same_row = |i: usize| (pl.get(i).expect("pt").y - pr.get(i).expect("pt").y).abs() <= 2.0;
    let mut mask = Mat::default();
    find_fundamental_mat(&pl, &pr, FM_RANSAC, 1.0, 0.999, 5000, &mut mask).expect("F");
    let inlier_idx: Vec<usize> = (0..n)
        .filter(|&i| *mask.at::<u8>(i as i32).expect("mask") != 0)
        .collect();
    let inliers = inlier_idx.len();
    assert!(inliers >= 30, "only {inliers} epipolar inliers");
    RowAlignment {
        matches: n,
        all: (0..n).filter(|&i| same_row(i)).count() as f64 / n as f64,
        inliers,
        inlier: inlier_idx.iter().filter(|&&i| same_row(i)).count() as f64 / inliers as f64,
    }
}

#[test]
fn euroc_rectification_aligns_rows() {
    let Some(dir) = euroc_dir("euroc_rectification_aligns_rows") else {
        return;
    };
    let seq = EurocSequence::open(&dir).expect("open EuRoC");
    let rect = StereoRectifier::from_euroc(seq.cam0(), seq.cam1()).expect("rectifier");
    println!(
        "rectified fx {:.3} fy {:.3} cx {:.3} cy {:.3} baseline {:.5} m",
        rect.fx(),
        rect.fy(),
        rect.cx(),
        rect.cy(),
        rect.baseline()
    );
    assert!(
        (rect.baseline() - 0.110).abs() < 0.005,
        "baseline {}",
        rect.baseline()
    );
    assert!(rect.fx() > 300.0 && rect.fx() < 600.0);

    let frame = &seq.frames()[0];
    let (left, right) = (gray(&frame.left), gray(&frame.right));
    let pair = rect.rectify(&left, &right).expect("rectify");
    assert_eq!(pair.left.size().expect("size"), left.size().expect("size"));
    assert_eq!(
        pair.right.size().expect("size"),
        right.size().expect("size")
    );
    assert_eq!(pair.left.typ(), left.typ());

    let before = row_alignment(&left, &right);
    let after = row_alignment(&pair.left, &pair.right);
    for (name, a) in [("raw", &before), ("rectified", &after)] {
        println!(
            "{name}: same-row (|dy| <= 2 px) fraction {:.3} of {} cross-checked matches, \
             {:.3} of {} RANSAC-F inliers",
            a.all, a.matches, a.inlier, a.inliers
        );
    }
    assert!(
        after.inlier >= 0.8,
        "only {:.3} of rectified epipolar inliers on the same row",
        after.inlier
    );
    assert!(
        after.all > 2.0 * before.all,
        "rectification did not improve row alignment"
    );
    assert!(before.inlier < 0.5, "raw images already row-aligned?");

    // A wrongly sized image is a typed error.
    let small = Mat::new_rows_cols_with_default(10, 10, left.typ(), 0.into()).expect("mat");
    assert!(matches!(
        rect.rectify(&small, &right),
        Err(spslam::dataset::DatasetError::ImageSizeMismatch { width: 10, .. })
    ));
}
