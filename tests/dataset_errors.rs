//! Typed errors of the dataset readers, each on a minimal layout written
//! into a temporary folder (no shared data needed).

use std::fs;
use std::path::{Path, PathBuf};

use opencv::core::{Mat, Scalar, CV_8UC1};
use spslam::dataset::{DatasetError, EurocSequence, KittiSequence};

const P0: &str = "P0: 7.070912e+02 0 6.018873e+02 0 0 7.070912e+02 1.831104e+02 0 0 0 1 0";
const P1: &str =
    "P1: 7.070912e+02 0 6.018873e+02 -3.798145e+02 0 7.070912e+02 1.831104e+02 0 0 0 1 0";

/// The original EuRoC V1_01 cam0 `sensor.yaml`.
const CAM0_YAML: &str = "%YAML:1.0
# General sensor definitions.
sensor_type: camera
comment: VI-Sensor cam0 (MT9M034)

# Sensor extrinsics wrt. the body-frame.
T_BS:
  cols: 4
  rows: 4
  data: [0.0148655429818, -0.999880929698, 0.00414029679422, -0.0216401454975,
         0.999557249008, 0.0149672133247, 0.025715529948, -0.064676986768,
        -0.0257744366974, 0.00375618835797, 0.999660727178, 0.00981073058949,
         0.0, 0.0, 0.0, 1.0]

# Camera specific definitions.
rate_hz: 20
resolution: [752, 480]
camera_model: pinhole
intrinsics: [458.654, 457.296, 367.215, 248.375] #fu, fv, cu, cv
distortion_model: radial-tangential
distortion_coefficients: [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05]
";

/// A fresh, empty temporary folder for one test.
fn temp_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("spslam-dataset-{tag}-{}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).expect("create temp dir");
    dir
}

fn write_png(path: &Path) {
    let img = Mat::new_rows_cols_with_default(4, 6, CV_8UC1, Scalar::all(128.0)).expect("mat");
    assert!(opencv::imgcodecs::imwrite_def(path, &img).expect("imwrite"));
}

/// `root/sequences/00` with `n` stereo images, `times` rows and `calib`.
fn kitti_layout(tag: &str, n: usize, times: usize, calib: &str) -> (PathBuf, PathBuf) {
    let root = temp_dir(tag);
    let seq = root.join("sequences/00");
    for cam in ["image_0", "image_1"] {
        fs::create_dir_all(seq.join(cam)).expect("mkdir");
        for i in 0..n {
            write_png(&seq.join(cam).join(format!("{i:06}.png")));
        }
    }
    fs::write(seq.join("calib.txt"), calib).expect("calib");
    let rows: String = (0..times)
        .map(|i| format!("{:e}\n", i as f64 * 0.1))
        .collect();
    fs::write(seq.join("times.txt"), rows).expect("times");
    (root, seq)
}

fn good_calib() -> String {
    format!("{P0}\n{P1}\n")
}

#[test]
fn kitti_minimal_layout_opens() {
    let (root, _) = kitti_layout("kitti-ok", 3, 3, &good_calib());
    let seq = KittiSequence::open(&root, "00").expect("open");
    assert_eq!(seq.frames().len(), 3);
    assert!((seq.calibration().baseline - 0.537).abs() < 1e-3);
    assert_eq!(seq.ground_truth_path(), None);
    fs::remove_dir_all(root).ok();
}

#[test]
fn kitti_missing_folder() {
    let (root, seq) = kitti_layout("kitti-missing", 3, 3, &good_calib());
    fs::remove_dir_all(seq.join("image_1")).expect("rm");
    let err = KittiSequence::open(&root, "00").expect_err("must fail");
    let msg = err.to_string();
    match err {
        DatasetError::MissingFolder { path } => assert_eq!(path, seq.join("image_1")),
        other => panic!("unexpected {other:?}"),
    }
    assert!(msg.contains("image_1"), "{msg}");

    let err = KittiSequence::open(&root, "07").expect_err("no sequence 07");
    assert!(
        matches!(err, DatasetError::MissingFolder { ref path } if path.ends_with("sequences/07"))
    );
    fs::remove_dir_all(root).ok();
}

#[test]
fn kitti_malformed_calib_row_names_the_line() {
    let short = P1.rsplit_once(' ').expect("space").0; // 11 numbers
    let (root, seq) = kitti_layout("kitti-calib", 3, 3, &format!("{P0}\n{short}\n"));
    let err = KittiSequence::open(&root, "00").expect_err("must fail");
    let msg = err.to_string();
    let calib = seq.join("calib.txt");
    match err {
        DatasetError::MalformedRow { path, line, reason } => {
            assert_eq!(path, calib);
            assert_eq!(line, 2);
            assert!(reason.contains("11 numbers"), "{reason}");
        }
        other => panic!("unexpected {other:?}"),
    }
    assert!(msg.contains(&format!("{}:2", calib.display())), "{msg}");

    // A non-number, after a comment line: line 3.
    let bad = P1.replace("-3.798145e+02", "-3.79x");
    fs::write(&calib, format!("# c\n{P0}\n{bad}\n")).expect("calib");
    let err = KittiSequence::open(&root, "00").expect_err("must fail");
    assert!(
        matches!(err, DatasetError::MalformedRow { line: 3, .. }),
        "{err:?}"
    );
    assert!(err.to_string().contains("-3.79x"), "{err}");

    // P1 absent.
    fs::write(&calib, format!("{P0}\n")).expect("calib");
    let err = KittiSequence::open(&root, "00").expect_err("must fail");
    assert!(
        matches!(err, DatasetError::MissingKey { ref key, .. } if key == "P1"),
        "{err:?}"
    );
    fs::remove_dir_all(root).ok();
}

#[test]
fn kitti_count_mismatches() {
    let (root, seq) = kitti_layout("kitti-times", 3, 4, &good_calib());
    let err = KittiSequence::open(&root, "00").expect_err("must fail");
    let msg = err.to_string();
    match err {
        DatasetError::TimestampCountMismatch {
            path,
            timestamps,
            images,
        } => {
            assert_eq!(path, seq.join("times.txt"));
            assert_eq!((timestamps, images), (4, 3));
        }
        other => panic!("unexpected {other:?}"),
    }
    assert!(msg.contains("times.txt"), "{msg}");

    fs::remove_file(seq.join("image_1/000002.png")).expect("rm");
    let err = KittiSequence::open(&root, "00").expect_err("must fail");
    assert!(
        matches!(
            err,
            DatasetError::ImageCountMismatch {
                left: 3,
                right: 2,
                ..
            }
        ),
        "{err:?}"
    );
    assert!(err.to_string().contains("image_1"), "{err}");
    fs::remove_dir_all(root).ok();
}

/// `root/mav0` with two cameras of `n` images and the given cam0 yaml.
fn euroc_layout(tag: &str, n: usize, cam0_yaml: &str) -> PathBuf {
    let root = temp_dir(tag);
    for cam in ["cam0", "cam1"] {
        let dir = root.join("mav0").join(cam);
        fs::create_dir_all(dir.join("data")).expect("mkdir");
        let mut csv = String::from("#timestamp [ns],filename\n");
        for i in 0..n {
            let t = 1_403_715_273_262_142_976_u64 + i as u64 * 50_000_000;
            write_png(&dir.join("data").join(format!("{t}.png")));
            csv.push_str(&format!("{t},{t}.png\n"));
        }
        fs::write(dir.join("data.csv"), csv).expect("csv");
        let yaml = if cam == "cam0" { cam0_yaml } else { CAM0_YAML };
        fs::write(dir.join("sensor.yaml"), yaml).expect("yaml");
    }
    root
}

#[test]
fn euroc_minimal_layout_opens() {
    let root = euroc_layout("euroc-ok", 3, CAM0_YAML);
    let seq = EurocSequence::open(&root).expect("open");
    assert_eq!(seq.frames().len(), 3);
    assert_eq!(seq.cam0().fx, 458.654);
    assert_eq!(seq.cam0().t_bs[(2, 3)], 0.00981073058949);
    assert!(seq.imu().is_empty());
    fs::remove_dir_all(root).ok();
}

#[test]
fn euroc_malformed_sensor_yaml_value_names_the_line() {
    let yaml = CAM0_YAML.replace("457.296", "457.2x6");
    let root = euroc_layout("euroc-yaml", 2, &yaml);
    let path = root.join("mav0/cam0/sensor.yaml");
    let err = EurocSequence::open(&root).expect_err("must fail");
    let msg = err.to_string();
    match err {
        DatasetError::MalformedRow {
            path: p,
            line,
            reason,
        } => {
            assert_eq!(p, path);
            assert_eq!(line, 19, "intrinsics is on line 19");
            assert!(reason.contains("intrinsics[1]"), "{reason}");
        }
        other => panic!("unexpected {other:?}"),
    }
    assert!(msg.contains(&format!("{}:19", path.display())), "{msg}");

    // A bad number on a continuation line of T_BS.data names that line.
    let yaml = CAM0_YAML.replace("0.999557249008", "0.99955x");
    fs::write(&path, yaml).expect("yaml");
    let err = EurocSequence::open(&root).expect_err("must fail");
    assert!(
        matches!(err, DatasetError::MalformedRow { line: 11, .. }),
        "{err:?}"
    );

    // Too few distortion coefficients.
    let yaml = CAM0_YAML.replace(", 1.76187114e-05]", "]");
    fs::write(&path, yaml).expect("yaml");
    let err = EurocSequence::open(&root).expect_err("must fail");
    assert!(
        matches!(err, DatasetError::MalformedRow { line: 21, .. }),
        "{err:?}"
    );

    // A missing key.
    let yaml = CAM0_YAML.replace("intrinsics:", "# intrinsics:");
    fs::write(&path, yaml).expect("yaml");
    let err = EurocSequence::open(&root).expect_err("must fail");
    assert!(matches!(err, DatasetError::MissingKey { ref key, .. } if key == "intrinsics"));
    fs::remove_dir_all(root).ok();
}

#[test]
fn euroc_missing_folder_and_file() {
    let root = euroc_layout("euroc-missing", 2, CAM0_YAML);
    let csv = root.join("mav0/cam1/data.csv");
    let text = fs::read_to_string(&csv).expect("csv");
    fs::write(&csv, format!("{text}1403715273362142976,nope.png\n")).expect("csv");
    let err = EurocSequence::open(&root).expect_err("must fail");
    assert!(
        matches!(err, DatasetError::MissingFile { ref path } if path.ends_with("cam1/data/nope.png")),
        "{err:?}"
    );

    fs::remove_dir_all(root.join("mav0/cam1")).expect("rm");
    let err = EurocSequence::open(&root).expect_err("must fail");
    assert!(err.to_string().contains("cam1"), "{err}");
    assert!(
        matches!(err, DatasetError::MissingFolder { ref path } if path.ends_with("mav0/cam1")),
        "{err:?}"
    );
    fs::remove_dir_all(root).ok();
}
