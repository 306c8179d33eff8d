//! Writes a synthetic sequence to disk in the KITTI odometry layout, with
//! TUM RGB-D lists and depth maps beside it:
//!
//! ```text
//! ROOT/sequences/NAME/image_0/000000.png   left images (8-bit gray)
//! ROOT/sequences/NAME/image_1/000000.png   right images
//! ROOT/sequences/NAME/depth/000000.png     left depth, 16-bit, 5000 per metre, 0 = none
//! ROOT/sequences/NAME/calib.txt            P0..P3 and Tr, as KITTI's
//! ROOT/sequences/NAME/times.txt            seconds, one a line
//! ROOT/sequences/NAME/rgb.txt, depth.txt, groundtruth.txt   TUM RGB-D lists
//! ROOT/sequences/NAME/synthetic.json       the config that made it
//! ROOT/poses/NAME.txt                      ground truth T_w_c0, 12 numbers a line
//! ```
//!
//! `KittiSequence::open(ROOT, NAME)` reads it and finds the ground truth;
//! `TumRgbdSequence::open(ROOT/sequences/NAME, …)` reads it as RGB-D.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use nalgebra::Isometry3;
use opencv::core::{Mat, Vector};
use opencv::prelude::*;

use super::error::{Result, SyntheticError};
use super::sequence::{SyntheticFrame, SyntheticSequence};

/// Depth units per metre in the depth PNGs (TUM RGB-D's).
pub const DEPTH_UNITS_PER_METRE: f64 = 5000.0;

/// Where and what to write.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct WriteOptions {
    /// The sequence's name under `sequences/` (KITTI's two digits, e.g. `00`).
    pub sequence_name: String,
    /// Write the depth maps (and the TUM lists).
    pub with_depth: bool,
    /// Replace a sequence folder that already holds files.
    pub overwrite: bool,
}

impl Default for WriteOptions {
    fn default() -> Self {
        Self {
            sequence_name: "00".into(),
            with_depth: true,
            overwrite: false,
        }
    }
}

/// The paths of a written sequence.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct WrittenSequence {
    /// `ROOT/sequences/NAME`.
    pub sequence_dir: PathBuf,
    /// `ROOT/poses/NAME.txt`.
    pub poses_path: PathBuf,
    /// Number of frames written.
    pub frames: usize,
}

/// Renders every frame of `sequence` and writes it under `root`, calling
/// `progress(done, total)` after each frame.
pub fn write_sequence(
    sequence: &SyntheticSequence,
    root: &Path,
    options: &WriteOptions,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<WrittenSequence> {
    let name = &options.sequence_name;
    if name.is_empty() || name.contains(['/', '\\']) || name == "." || name == ".." {
        return Err(SyntheticError::InvalidConfig {
            field: "sequence_name",
            reason: format!("is `{name}`; it must be a plain folder name such as 00"),
        });
    }
    let sequence_dir = root.join("sequences").join(name);
    let poses_path = root.join("poses").join(format!("{name}.txt"));
    prepare_folder(&sequence_dir, &poses_path, options.overwrite)?;
    let mut folders = vec!["image_0", "image_1"];
    if options.with_depth {
        folders.push("depth");
    }
    for folder in &folders {
        create_dir(&sequence_dir.join(folder))?;
    }
    create_dir(&root.join("poses"))?;

    write_text(&sequence_dir.join("calib.txt"), &calib_text(sequence))?;
    let config_json =
        serde_json::to_string_pretty(sequence.config()).map_err(|e| SyntheticError::Io {
            path: sequence_dir.join("synthetic.json"),
            source: std::io::Error::other(e),
        })?;
    write_text(&sequence_dir.join("synthetic.json"), &config_json)?;

    let total = sequence.len();
    let mut times = String::new();
    let mut poses = String::new();
    let mut tum_rgb = String::from("# timestamp filename (synthetic left camera)\n");
    let mut tum_depth = String::from("# timestamp filename (16-bit, 5000 per metre, 0 = none)\n");
    let mut tum_truth = String::from("# timestamp tx ty tz qx qy qz qw\n");
    for index in 0..total {
        let frame = sequence.render(index, options.with_depth);
        let file = format!("{index:06}.png");
        write_gray(
            &sequence_dir.join("image_0").join(&file),
            &frame,
            &frame.left,
        )?;
        write_gray(
            &sequence_dir.join("image_1").join(&file),
            &frame,
            &frame.right,
        )?;
        let _ = writeln!(times, "{}", c_exponential(frame.timestamp, 6));
        poses.push_str(&kitti_pose_line(&frame.pose));
        if options.with_depth {
            write_depth(&sequence_dir.join("depth").join(&file), &frame)?;
            let t = frame.timestamp;
            let _ = writeln!(tum_rgb, "{t:.6} image_0/{file}");
            let _ = writeln!(tum_depth, "{t:.6} depth/{file}");
            tum_truth.push_str(&tum_pose_line(t, &frame.pose));
        }
        progress(index + 1, total);
    }
    write_text(&sequence_dir.join("times.txt"), &times)?;
    write_text(&poses_path, &poses)?;
    if options.with_depth {
        write_text(&sequence_dir.join("rgb.txt"), &tum_rgb)?;
        write_text(&sequence_dir.join("depth.txt"), &tum_depth)?;
        write_text(&sequence_dir.join("groundtruth.txt"), &tum_truth)?;
    }
    Ok(WrittenSequence {
        sequence_dir,
        poses_path,
        frames: total,
    })
}

/// Refuses a non-empty sequence folder unless overwriting, then clears it.
fn prepare_folder(sequence_dir: &Path, poses_path: &Path, overwrite: bool) -> Result<()> {
    let occupied = match std::fs::read_dir(sequence_dir) {
        Ok(mut entries) => entries.next().is_some(),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => false,
        Err(e) => return Err(SyntheticError::io(sequence_dir)(e)),
    };
    if occupied {
        if !overwrite {
            return Err(SyntheticError::OutputNotEmpty {
                path: sequence_dir.to_path_buf(),
            });
        }
        std::fs::remove_dir_all(sequence_dir).map_err(SyntheticError::io(sequence_dir))?;
        if poses_path.is_file() {
            std::fs::remove_file(poses_path).map_err(SyntheticError::io(poses_path))?;
        }
    }
    Ok(())
}

fn create_dir(path: &Path) -> Result<()> {
    std::fs::create_dir_all(path).map_err(SyntheticError::io(path))
}

fn write_text(path: &Path, text: &str) -> Result<()> {
    std::fs::write(path, text).map_err(SyntheticError::io(path))
}

/// KITTI's `calib.txt`: P0 = P2 (left), P1 = P3 (right, −f·b in the last
/// column of the first row), Tr the identity.
fn calib_text(sequence: &SyntheticSequence) -> String {
    let [p0, p1] = sequence.camera().kitti_projections();
    let identity = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    let mut text = String::new();
    for (key, values) in [
        ("P0", p0),
        ("P1", p1),
        ("P2", p0),
        ("P3", p1),
        ("Tr", identity),
    ] {
        let numbers: Vec<String> = values.iter().map(|v| c_exponential(*v, 12)).collect();
        let _ = writeln!(text, "{key}: {}", numbers.join(" "));
    }
    text
}

/// One line of a KITTI pose file: the top 3×4 of T_wc, row-major.
pub fn kitti_pose_line(pose: &Isometry3<f64>) -> String {
    let m = pose.to_homogeneous();
    let numbers: Vec<String> = (0..12)
        .map(|i| c_exponential(m[(i / 4, i % 4)], 12))
        .collect();
    numbers.join(" ") + "\n"
}

/// One line of a TUM trajectory: `t tx ty tz qx qy qz qw`.
fn tum_pose_line(t: f64, pose: &Isometry3<f64>) -> String {
    let p = pose.translation.vector;
    let q = pose.rotation.coords; // (i, j, k, w)
    format!(
        "{t:.6} {:.9} {:.9} {:.9} {:.9} {:.9} {:.9} {:.9}\n",
        p.x, p.y, p.z, q.x, q.y, q.z, q.w
    )
}

/// C's `%.{digits}e`: a signed exponent of at least two digits (`1.5e+02`).
pub fn c_exponential(value: f64, digits: usize) -> String {
    let rust = format!("{value:.digits$e}");
    let Some((mantissa, exponent)) = rust.split_once('e') else {
        return rust;
    };
    let exponent: i32 = exponent.parse().unwrap_or(0);
    let sign = if exponent < 0 { '-' } else { '+' };
    format!("{mantissa}e{sign}{:02}", exponent.abs())
}

fn write_gray(path: &Path, frame: &SyntheticFrame, pixels: &[u8]) -> Result<()> {
    let failed = |reason: String| SyntheticError::ImageWrite {
        path: path.to_path_buf(),
        reason,
    };
    let flat = Mat::from_slice(pixels).map_err(|e| failed(e.to_string()))?;
    let image = flat
        .reshape(1, frame.height as i32)
        .map_err(|e| failed(e.to_string()))?;
    imwrite(path, &image)
}

/// The depth map as 16-bit PNG: Z·5000 rounded; 0 for the sky and beyond
/// 65535/5000 ≈ 13.1 m, which 16 bits cannot hold.
fn write_depth(path: &Path, frame: &SyntheticFrame) -> Result<()> {
    let units: Vec<u16> = frame
        .depth
        .iter()
        .map(|&z| {
            let d = (z as f64 * DEPTH_UNITS_PER_METRE).round();
            if (1.0..=u16::MAX as f64).contains(&d) {
                d as u16
            } else {
                0
            }
        })
        .collect();
    let failed = |reason: String| SyntheticError::ImageWrite {
        path: path.to_path_buf(),
        reason,
    };
    let flat = Mat::from_slice(&units).map_err(|e| failed(e.to_string()))?;
    let image = flat
        .reshape(1, frame.height as i32)
        .map_err(|e| failed(e.to_string()))?;
    imwrite(path, &image)
}

fn imwrite(path: &Path, image: &impl opencv::core::ToInputArray) -> Result<()> {
    let failed = |reason: String| SyntheticError::ImageWrite {
        path: path.to_path_buf(),
        reason,
    };
    let name = path
        .to_str()
        .ok_or_else(|| failed("the path is not valid UTF-8".into()))?;
    match opencv::imgcodecs::imwrite(name, image, &Vector::new()) {
        Ok(true) => Ok(()),
        Ok(false) => Err(failed("OpenCV's imwrite returned false".into())),
        Err(e) => Err(failed(e.to_string())),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exponentials_are_formatted_like_c() {
        assert_eq!(c_exponential(718.856, 12), "7.188560000000e+02");
        assert_eq!(c_exponential(-0.0015, 6), "-1.500000e-03");
        assert_eq!(c_exponential(0.0, 6), "0.000000e+00");
        assert_eq!(c_exponential(1e-120, 2), "1.00e-120");
    }

    #[test]
    fn identity_pose_line_is_kitti_first_line() {
        let line = kitti_pose_line(&Isometry3::identity());
        let numbers: Vec<f64> = line
            .split_whitespace()
            .map(|s| s.parse().unwrap())
            .collect();
        assert_eq!(
            numbers,
            vec![1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0]
        );
    }
}
