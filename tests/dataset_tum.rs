//! TUM RGB-D reader on a small synthetic sequence.

use std::fs;
use std::path::{Path, PathBuf};

use opencv::core::{Mat, Scalar, CV_16UC1, CV_8UC3};
use spslam::dataset::{DatasetError, TumRgbdSequence, DEFAULT_MAX_DIFFERENCE};

fn temp_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("spslam-dataset-{tag}-{}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).expect("create temp dir");
    dir
}

fn write_png(path: &Path, typ: i32) {
    let img = Mat::new_rows_cols_with_default(4, 6, typ, Scalar::all(100.0)).expect("mat");
    assert!(opencv::imgcodecs::imwrite_def(path, &img).expect("imwrite"));
}

/// Writes `rgb.txt` / `depth.txt` lists and their PNGs; returns the folder.
fn tum_layout(tag: &str, rgb: &[&str], depth: &[&str]) -> PathBuf {
    let dir = temp_dir(tag);
    for (name, stamps, typ) in [("rgb", rgb, CV_8UC3), ("depth", depth, CV_16UC1)] {
        fs::create_dir_all(dir.join(name)).expect("mkdir");
        let mut list = format!("# {name} maps\n# file: 'synthetic'\n# timestamp filename\n");
        for t in stamps {
            write_png(&dir.join(format!("{name}/{t}.png")), typ);
            list.push_str(&format!("{t} {name}/{t}.png\n"));
        }
        fs::write(dir.join(format!("{name}.txt")), list).expect("list");
    }
    fs::write(
        dir.join("groundtruth.txt"),
        "# ground truth trajectory\n# timestamp tx ty tz qx qy qz qw\n1.0 0 0 0 0 0 0 1\n",
    )
    .expect("gt");
    dir
}

#[test]
fn associates_nearest_within_tolerance_and_drops_unmatched() {
    // depth 1.062 is within 0.02 s of rgb 1.050 (0.012) and 1.070 (0.008):
    // the nearer, 1.070, gets it and 1.050 is dropped (one-to-one).
    // rgb 1.100 has no depth within 0.02 s; depth 1.300 has no rgb.
    let rgb = ["1.000000", "1.050000", "1.070000", "1.100000", "1.150000"];
    let depth = ["1.005000", "1.062000", "1.160000", "1.300000"];
    let dir = tum_layout("tum-assoc", &rgb, &depth);
    let seq = TumRgbdSequence::open(&dir, DEFAULT_MAX_DIFFERENCE).expect("open");
    let pairs: Vec<(f64, f64)> = seq
        .frames()
        .iter()
        .map(|f| (f.timestamp, f.depth_timestamp))
        .collect();
    assert_eq!(pairs, vec![(1.0, 1.005), (1.07, 1.062), (1.15, 1.16)]);
    assert_eq!((seq.unmatched_rgb(), seq.unmatched_depth()), (2, 1));
    let f = &seq.frames()[1];
    assert!(f.rgb.ends_with("rgb/1.070000.png") && f.rgb.is_file());
    assert!(f.depth.ends_with("depth/1.062000.png") && f.depth.is_file());
    assert_eq!(seq.ground_truth_path(), Some(dir.join("groundtruth.txt")));

    // A tighter tolerance keeps only the closest pairs.
    let tight = TumRgbdSequence::open(&dir, 0.006).expect("open");
    let kept: Vec<f64> = tight.frames().iter().map(|f| f.timestamp).collect();
    assert_eq!(kept, vec![1.0]);
    fs::remove_dir_all(dir).ok();
}

#[test]
fn malformed_list_row_and_missing_image() {
    let dir = tum_layout("tum-bad", &["1.000000"], &["1.001000"]);
    fs::write(dir.join("depth.txt"), "# header\n1.001000\n").expect("list");
    let err = TumRgbdSequence::open(&dir, DEFAULT_MAX_DIFFERENCE).expect_err("must fail");
    assert!(
        matches!(err, DatasetError::MalformedRow { line: 2, .. }),
        "{err:?}"
    );
    assert!(err.to_string().contains("depth.txt:2"), "{err}");

    fs::write(dir.join("depth.txt"), "1.001000 depth/missing.png\n").expect("list");
    let err = TumRgbdSequence::open(&dir, DEFAULT_MAX_DIFFERENCE).expect_err("must fail");
    assert!(
        matches!(err, DatasetError::MissingFile { ref path } if path.ends_with("depth/missing.png"))
    );

    let err = TumRgbdSequence::open(dir.join("nope"), DEFAULT_MAX_DIFFERENCE).expect_err("no dir");
    assert!(matches!(err, DatasetError::MissingFolder { .. }));
    fs::remove_dir_all(dir).ok();
}
