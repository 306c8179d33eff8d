//! Trajectory files: reading, writing, format detection and malformed input.

use std::path::PathBuf;

use nalgebra::{Isometry3, Vector3};
use spslam::eval::{read_trajectory, write_trajectory, EvalError, Trajectory, TrajectoryFormat};

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("spslam_eval_io_{}_{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn sample() -> Trajectory {
    let poses = (0..5)
        .map(|i| {
            let f = i as f64;
            Isometry3::new(
                Vector3::new(f, 0.5 * f, -f),
                Vector3::new(0.1 * f, -0.2, 0.05 * f),
            )
        })
        .collect();
    Trajectory::new((0..5).map(|i| 1000.0 + 0.1 * i as f64).collect(), poses)
}

#[test]
fn round_trip_in_every_format() {
    let dir = temp_dir("round_trip");
    let t = sample();
    for (format, name) in [
        (TrajectoryFormat::Kitti, "t.txt"),
        (TrajectoryFormat::Tum, "t.tum"),
        (TrajectoryFormat::Euroc, "t.csv"),
    ] {
        let path = dir.join(name);
        write_trajectory(&path, &t, format).unwrap();
        assert_eq!(TrajectoryFormat::detect(&path).unwrap(), format);
        let back = read_trajectory(&path, format).unwrap();
        assert_eq!(back.len(), t.len());
        for (a, b) in back.poses.iter().zip(&t.poses) {
            assert!(
                (a.translation.vector - b.translation.vector).norm() < 1e-8,
                "{format}"
            );
            assert!(a.rotation.angle_to(&b.rotation) < 1e-8, "{format}");
        }
        if format != TrajectoryFormat::Kitti {
            for (a, b) in back.timestamps.iter().zip(&t.timestamps) {
                assert!((a - b).abs() < 1e-6, "{format}: {a} vs {b}");
            }
        } else {
            assert_eq!(back.timestamps, vec![0.0, 1.0, 2.0, 3.0, 4.0]);
        }
    }
}

#[test]
fn malformed_row_names_file_and_line() {
    let dir = temp_dir("malformed");
    let path = dir.join("bad.txt");
    std::fs::write(&path, "# header\n1 0 0 0 0 0 0 1\n\n2 0 0 x 0 0 0 1\n").unwrap();
    let err = read_trajectory(&path, TrajectoryFormat::Tum).unwrap_err();
    match &err {
        EvalError::Malformed { path: p, line, .. } => {
            assert_eq!(p, &path);
            assert_eq!(*line, 4);
        }
        other => panic!("unexpected {other:?}"),
    }
    assert!(err.to_string().contains("bad.txt:4"), "{err}");

    let kitti = dir.join("short.txt");
    std::fs::write(&kitti, "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1\n").unwrap();
    let err = read_trajectory(&kitti, TrajectoryFormat::Kitti).unwrap_err();
    assert!(
        matches!(err, EvalError::Malformed { line: 2, .. }),
        "{err:?}"
    );
}

#[test]
fn missing_empty_and_unknown() {
    let dir = temp_dir("missing");
    let err = read_trajectory(&dir.join("nope.txt"), TrajectoryFormat::Tum).unwrap_err();
    assert!(matches!(err, EvalError::Io { .. }));
    let empty = dir.join("empty.txt");
    std::fs::write(&empty, "# nothing\n\n").unwrap();
    assert!(matches!(
        read_trajectory(&empty, TrajectoryFormat::Kitti),
        Err(EvalError::Empty { .. })
    ));
    let odd = dir.join("odd.txt");
    std::fs::write(&odd, "1 2 3\n").unwrap();
    assert!(matches!(
        TrajectoryFormat::detect(&odd),
        Err(EvalError::UndetectedFormat { columns: 3, .. })
    ));
    assert!("TUM".parse::<TrajectoryFormat>().is_ok());
    assert!(matches!(
        "bag".parse::<TrajectoryFormat>(),
        Err(EvalError::UnknownFormat { .. })
    ));
}
