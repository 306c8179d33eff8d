//! EuRoC `data.csv` files: camera image lists and IMU samples.

use std::path::{Path, PathBuf};

use nalgebra::Vector3;

use super::error::{DatasetError, Result};
use super::text::{data_lines, ns_to_s, parse_f64, parse_ns, read_text, require_increasing};

/// One IMU measurement (`imu0/data.csv`), in the IMU sensor frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuSample {
    /// Time in seconds (nanoseconds / 1e9).
    pub t: f64,
    /// Angular velocity `w_RS_S` in rad/s.
    pub gyro: Vector3<f64>,
    /// Linear acceleration `a_RS_S` in m/s².
    pub accel: Vector3<f64>,
}

/// One row of a camera `data.csv`.
#[derive(Debug, Clone)]
pub(crate) struct CameraImage {
    /// Time in nanoseconds.
    pub t_ns: u64,
    /// Path of the image file (checked to exist).
    pub path: PathBuf,
}

/// Reads `camX/data.csv` (`timestamp_ns,filename`), resolving file names in
/// `image_dir` and checking that each file exists.
pub(crate) fn read_image_list(csv: &Path, image_dir: &Path) -> Result<Vec<CameraImage>> {
    let text = read_text(csv)?;
    let mut images: Vec<CameraImage> = Vec::new();
    for line in data_lines(&text) {
        let fields: Vec<&str> = line.text.split(',').map(str::trim).collect();
        let [t, name] = fields[..] else {
            return Err(DatasetError::row(
                csv,
                line.number,
                format!("{} fields, expected 2 (timestamp, filename)", fields.len()),
            ));
        };
        let t_ns = parse_ns(csv, line.number, t)?;
        require_increasing(csv, line.number, images.last().map(|i| i.t_ns), t_ns)?;
        let path = image_dir.join(name);
        if !path.is_file() {
            return Err(DatasetError::MissingFile { path });
        }
        images.push(CameraImage { t_ns, path });
    }
    Ok(images)
}

/// Reads `imu0/data.csv` (`timestamp_ns, wx, wy, wz, ax, ay, az`).
pub(crate) fn read_imu(csv: &Path) -> Result<Vec<ImuSample>> {
    let text = read_text(csv)?;
    let mut samples = Vec::new();
    let mut previous = None;
    for line in data_lines(&text) {
        let fields: Vec<&str> = line.text.split(',').collect();
        if fields.len() != 7 {
            return Err(DatasetError::row(
                csv,
                line.number,
                format!(
                    "{} fields, expected 7 (timestamp, w xyz, a xyz)",
                    fields.len()
                ),
            ));
        }
        let t_ns = parse_ns(csv, line.number, fields[0])?;
        require_increasing(csv, line.number, previous, t_ns)?;
        previous = Some(t_ns);
        let mut v = [0.0; 6];
        for (i, (slot, name)) in v
            .iter_mut()
            .zip(["wx", "wy", "wz", "ax", "ay", "az"])
            .enumerate()
        {
            *slot = parse_f64(csv, line.number, name, fields[i + 1])?;
        }
        samples.push(ImuSample {
            t: ns_to_s(t_ns),
            gyro: Vector3::new(v[0], v[1], v[2]),
            accel: Vector3::new(v[3], v[4], v[5]),
        });
    }
    Ok(samples)
}
