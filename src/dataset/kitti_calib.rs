//! KITTI odometry `calib.txt`: projection matrices P0..P3 and `Tr`.

use std::path::Path;

use nalgebra::Matrix3x4;

use super::error::{DatasetError, Result};
use super::text::{data_lines, parse_f64, read_text};

/// The calibration of a KITTI odometry sequence (`calib.txt`).
///
/// The focal lengths and principal point are those of the rectified left
/// grey camera (P0); the baseline is that of the grey stereo pair.
#[derive(Debug, Clone, PartialEq)]
pub struct KittiCalibration {
    /// Projection matrix of the left grey camera.
    pub p0: Matrix3x4<f64>,
    /// Projection matrix of the right grey camera.
    pub p1: Matrix3x4<f64>,
    /// Projection matrix of the left colour camera, when given.
    pub p2: Option<Matrix3x4<f64>>,
    /// Projection matrix of the right colour camera, when given.
    pub p3: Option<Matrix3x4<f64>>,
    /// Velodyne-to-camera-0 transform `Tr`, when given.
    pub tr: Option<Matrix3x4<f64>>,
    /// Focal length in x (pixels), `P0[0,0]`.
    pub fx: f64,
    /// Focal length in y (pixels), `P0[1,1]`.
    pub fy: f64,
    /// Principal point x (pixels), `P0[0,2]`.
    pub cx: f64,
    /// Principal point y (pixels), `P0[1,2]`.
    pub cy: f64,
    /// Stereo baseline in metres, `−P1[0,3] / fx`.
    pub baseline: f64,
}

impl KittiCalibration {
    /// Reads and checks `calib.txt`. Rows are `KEY: 12 numbers`; keys other
    /// than P0..P3 and `Tr` are ignored. P0 and P1 are required.
    pub fn from_file(path: &Path) -> Result<Self> {
        let text = read_text(path)?;
        let mut mats: [Option<Matrix3x4<f64>>; 5] = [None; 5];
        for line in data_lines(&text) {
            let (key, values) = line.text.split_once(':').ok_or_else(|| {
                DatasetError::row(path, line.number, "expected `KEY: 12 numbers`")
            })?;
            let key = key.trim();
            let slot = match key {
                "P0" => 0,
                "P1" => 1,
                "P2" => 2,
                "P3" => 3,
                "Tr" => 4,
                _ => continue,
            };
            mats[slot] = Some(parse_matrix(path, line.number, key, values)?);
        }
        let [p0, p1, p2, p3, tr] = mats;
        let missing = |key: &str| DatasetError::MissingKey {
            path: path.to_path_buf(),
            key: key.to_string(),
        };
        let p0 = p0.ok_or_else(|| missing("P0"))?;
        let p1 = p1.ok_or_else(|| missing("P1"))?;
        let fx = p0[(0, 0)];
        if fx <= 0.0 {
            return Err(DatasetError::InvalidCalibration {
                reason: format!("{}: P0 has fx = {fx}", path.display()),
            });
        }
        Ok(Self {
            fx,
            fy: p0[(1, 1)],
            cx: p0[(0, 2)],
            cy: p0[(1, 2)],
            baseline: -p1[(0, 3)] / fx,
            p0,
            p1,
            p2,
            p3,
            tr,
        })
    }
}

/// Parses 12 row-major numbers into a 3×4 matrix.
fn parse_matrix(path: &Path, line: usize, key: &str, values: &str) -> Result<Matrix3x4<f64>> {
    let fields: Vec<&str> = values.split_whitespace().collect();
    if fields.len() != 12 {
        return Err(DatasetError::row(
            path,
            line,
            format!("{key} has {} numbers, expected 12", fields.len()),
        ));
    }
    let mut m = Matrix3x4::zeros();
    for (i, f) in fields.iter().enumerate() {
        m[(i / 4, i % 4)] = parse_f64(path, line, &format!("{key}[{i}]"), f)?;
    }
    Ok(m)
}
