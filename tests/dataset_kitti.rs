//! KITTI odometry reader on the real sequence 06 excerpt.

mod common;

use spslam::dataset::KittiSequence;

#[test]
fn kitti_06_calibration_frames_and_ground_truth() {
    let Some(data) = common::data_dir("kitti_06_calibration_frames_and_ground_truth") else {
        return;
    };
    let seq = KittiSequence::open(data.join("kitti"), "06").expect("open KITTI 06");
    let c = seq.calibration();
    assert!((c.fx - 707.0912).abs() < 1e-9, "fx {}", c.fx);
    assert!((c.fy - 707.0912).abs() < 1e-9, "fy {}", c.fy);
    assert!((c.cx - 601.8873).abs() < 1e-9, "cx {}", c.cx);
    assert!((c.cy - 183.1104).abs() < 1e-9, "cy {}", c.cy);
    assert!((c.baseline - 0.537).abs() < 1e-3, "baseline {}", c.baseline);
    assert!(c.p2.is_none() && c.p3.is_none() && c.tr.is_none());

    let frames = seq.frames();
    assert_eq!(frames.len(), 51);
    assert!(frames.windows(2).all(|w| w[0].timestamp < w[1].timestamp));
    assert_eq!(frames[0].timestamp, 0.0);
    assert!(frames[0].left.ends_with("image_0/000000.png"));
    assert!(frames[50].right.ends_with("image_1/000050.png"));
    assert!(frames.iter().all(|f| f.left.is_file() && f.right.is_file()));

    let gt = seq
        .ground_truth_path()
        .expect("poses/06.txt beside sequences/");
    assert!(gt.ends_with("poses/06.txt"), "{}", gt.display());
}

#[test]
fn kitti_opens_from_sequence_dir_or_sequences_dir() {
    let Some(data) = common::data_dir("kitti_opens_from_sequence_dir_or_sequences_dir") else {
        return;
    };
    let root = KittiSequence::open(data.join("kitti"), "06").expect("root");
    let seqs = KittiSequence::open(data.join("kitti/sequences"), "06").expect("sequences/");
    let dir = KittiSequence::open(data.join("kitti/sequences/06"), "06").expect("sequence dir");
    assert_eq!(root.frames(), seqs.frames());
    assert_eq!(root.frames(), dir.frames());
    assert_eq!(dir.ground_truth_path(), root.ground_truth_path());
}
