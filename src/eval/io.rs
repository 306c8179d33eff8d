//! Reading and writing trajectory files (KITTI, TUM, EuRoC).

use std::io::Write;
use std::path::Path;

use nalgebra::{
    Isometry3, Matrix3, Matrix4, Quaternion, Rotation3, Translation3, UnitQuaternion, Vector3,
};

use super::error::{EvalError, Result};
use super::format::TrajectoryFormat;
use super::trajectory::Trajectory;

fn read_text(path: &Path) -> Result<String> {
    std::fs::read_to_string(path).map_err(|source| EvalError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// The data rows of a text file: (1-based line number, numbers), skipping blank and `#` lines.
fn numeric_rows(path: &Path, text: &str, separators: &[char]) -> Result<Vec<(usize, Vec<f64>)>> {
    let mut rows = Vec::new();
    for (index, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let numbers = line
            .split(separators)
            .map(str::trim)
            .filter(|t| !t.is_empty())
            .map(|t| {
                t.parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| EvalError::Malformed {
                        path: path.to_path_buf(),
                        line: index + 1,
                        reason: format!("{t:?} is not a finite number"),
                    })
            })
            .collect::<Result<Vec<f64>>>()?;
        rows.push((index + 1, numbers));
    }
    if rows.is_empty() {
        return Err(EvalError::Empty {
            path: path.to_path_buf(),
        });
    }
    Ok(rows)
}

fn expect_columns(path: &Path, line: usize, row: &[f64], wanted: usize, exact: bool) -> Result<()> {
    let ok = if exact {
        row.len() == wanted
    } else {
        row.len() >= wanted
    };
    if ok {
        return Ok(());
    }
    Err(EvalError::Malformed {
        path: path.to_path_buf(),
        line,
        reason: format!(
            "{} numbers, expected {}{wanted}",
            row.len(),
            if exact { "" } else { "at least " }
        ),
    })
}

/// A unit quaternion from (w, x, y, z), refusing a zero quaternion.
fn unit_quaternion(
    path: &Path,
    line: usize,
    w: f64,
    x: f64,
    y: f64,
    z: f64,
) -> Result<UnitQuaternion<f64>> {
    let q = Quaternion::new(w, x, y, z);
    if q.norm() < 1e-9 {
        return Err(EvalError::Malformed {
            path: path.to_path_buf(),
            line,
            reason: "zero quaternion".to_string(),
        });
    }
    Ok(UnitQuaternion::from_quaternion(q))
}

/// The rotation nearest to a (nearly orthonormal) 3×3 matrix.
fn nearest_rotation(m: &Matrix3<f64>) -> UnitQuaternion<f64> {
    let guess = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(*m));
    let rotation = Rotation3::from_matrix_eps(m, 1e-15, 100, guess.to_rotation_matrix());
    UnitQuaternion::from_rotation_matrix(&rotation)
}

/// Reads a KITTI pose file (12 numbers a line); the timestamps are the frame indices.
pub fn read_kitti(path: &Path) -> Result<Trajectory> {
    let text = read_text(path)?;
    let mut poses = Vec::new();
    let mut raw = Vec::new();
    for (line, row) in numeric_rows(path, &text, &[' ', '\t', ','])? {
        expect_columns(path, line, &row, 12, true)?;
        let mut matrix = Matrix4::identity();
        for (k, v) in row.iter().enumerate() {
            matrix[(k / 4, k % 4)] = *v;
        }
        raw.push(matrix);
        let m = Matrix3::new(
            row[0], row[1], row[2], row[4], row[5], row[6], row[8], row[9], row[10],
        );
        if m.determinant() <= 0.0 {
            return Err(EvalError::Malformed {
                path: path.to_path_buf(),
                line,
                reason: "the 3×3 part is not a rotation (determinant ≤ 0)".to_string(),
            });
        }
        let translation = Translation3::new(row[3], row[7], row[11]);
        poses.push(Isometry3::from_parts(translation, nearest_rotation(&m)));
    }
    let mut trajectory = Trajectory::from_poses(poses);
    trajectory.raw_matrices = Some(raw);
    Ok(trajectory)
}

/// A trajectory from 4×4 (or 3×4 padded) pose matrices held in memory, each
/// rotation made orthonormal as [`read_kitti`] does (the matrices are kept
/// as the raw ones for the KITTI metric); `timestamps` default to the
/// frame indices.
pub fn trajectory_from_matrices(
    matrices: Vec<Matrix4<f64>>,
    timestamps: Option<Vec<f64>>,
) -> Result<Trajectory> {
    let mut poses = Vec::with_capacity(matrices.len());
    for (index, matrix) in matrices.iter().enumerate() {
        let m: Matrix3<f64> = matrix.fixed_view::<3, 3>(0, 0).into_owned();
        let finite = matrix.iter().all(|v| v.is_finite());
        if !finite || m.determinant() <= 0.0 {
            return Err(EvalError::NotARotation { index });
        }
        let translation = Translation3::new(matrix[(0, 3)], matrix[(1, 3)], matrix[(2, 3)]);
        poses.push(Isometry3::from_parts(translation, nearest_rotation(&m)));
    }
    let mut trajectory = match timestamps {
        Some(stamps) if stamps.len() != poses.len() => {
            return Err(EvalError::StampCount {
                stamps: stamps.len(),
                poses: poses.len(),
            })
        }
        Some(stamps) => Trajectory::new(stamps, poses),
        None => Trajectory::from_poses(poses),
    };
    trajectory.raw_matrices = Some(matrices);
    Ok(trajectory)
}

/// Reads a KITTI pose file and its times file (one stamp in seconds a line).
pub fn read_kitti_with_times(path: &Path, times: &Path) -> Result<Trajectory> {
    let mut trajectory = read_kitti(path)?;
    let text = read_text(times)?;
    let mut stamps = Vec::new();
    for (line, row) in numeric_rows(times, &text, &[' ', '\t', ','])? {
        expect_columns(times, line, &row, 1, true)?;
        stamps.push(row[0]);
    }
    if stamps.len() != trajectory.len() {
        return Err(EvalError::TimesMismatch {
            path: times.to_path_buf(),
            times: stamps.len(),
            poses: trajectory.len(),
        });
    }
    trajectory.timestamps = stamps;
    Ok(trajectory)
}

/// Reads a TUM trajectory (`t tx ty tz qx qy qz qw`, `#` comments).
pub fn read_tum(path: &Path) -> Result<Trajectory> {
    let text = read_text(path)?;
    let mut timestamps = Vec::new();
    let mut poses = Vec::new();
    for (line, row) in numeric_rows(path, &text, &[' ', '\t', ','])? {
        expect_columns(path, line, &row, 8, true)?;
        let q = unit_quaternion(path, line, row[7], row[4], row[5], row[6])?;
        timestamps.push(row[0]);
        poses.push(Isometry3::from_parts(
            Translation3::new(row[1], row[2], row[3]),
            q,
        ));
    }
    Ok(Trajectory::new(timestamps, poses))
}

/// Reads an EuRoC ground-truth csv (`timestamp [ns], p_x, p_y, p_z, q_w, q_x, q_y, q_z, …`);
/// timestamps are converted to seconds.
pub fn read_euroc(path: &Path) -> Result<Trajectory> {
    let text = read_text(path)?;
    let mut timestamps = Vec::new();
    let mut poses = Vec::new();
    for (line, row) in numeric_rows(path, &text, &[','])? {
        expect_columns(path, line, &row, 8, false)?;
        let q = unit_quaternion(path, line, row[4], row[5], row[6], row[7])?;
        timestamps.push(row[0] / 1e9);
        poses.push(Isometry3::from_parts(
            Translation3::new(row[1], row[2], row[3]),
            q,
        ));
    }
    Ok(Trajectory::new(timestamps, poses))
}

/// Reads a trajectory in the given format.
pub fn read_trajectory(path: &Path, format: TrajectoryFormat) -> Result<Trajectory> {
    match format {
        TrajectoryFormat::Kitti => read_kitti(path),
        TrajectoryFormat::Tum => read_tum(path),
        TrajectoryFormat::Euroc => read_euroc(path),
    }
}

fn write_text(path: &Path, text: &str) -> Result<()> {
    let io = |source| EvalError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut file = std::fs::File::create(path).map_err(io)?;
    file.write_all(text.as_bytes()).map_err(io)
}

fn rotation_matrix(pose: &Isometry3<f64>) -> Matrix3<f64> {
    pose.rotation.to_rotation_matrix().into_inner()
}

fn translation(pose: &Isometry3<f64>) -> Vector3<f64> {
    pose.translation.vector
}

/// Writes a KITTI pose file (timestamps are not written).
pub fn write_kitti(path: &Path, trajectory: &Trajectory) -> Result<()> {
    let mut text = String::new();
    for pose in &trajectory.poses {
        let (r, t) = (rotation_matrix(pose), translation(pose));
        let values: Vec<String> = (0..3)
            .flat_map(|i| [r[(i, 0)], r[(i, 1)], r[(i, 2)], t[i]])
            .map(|v| format!("{v:.9e}"))
            .collect();
        text.push_str(&values.join(" "));
        text.push('\n');
    }
    write_text(path, &text)
}

/// Writes a TUM trajectory (`t tx ty tz qx qy qz qw`).
pub fn write_tum(path: &Path, trajectory: &Trajectory) -> Result<()> {
    let mut text = String::from("# timestamp tx ty tz qx qy qz qw\n");
    for (stamp, pose) in trajectory.timestamps.iter().zip(&trajectory.poses) {
        let (t, q) = (translation(pose), pose.rotation);
        text.push_str(&format!(
            "{stamp:.9} {:.9} {:.9} {:.9} {:.9} {:.9} {:.9} {:.9}\n",
            t.x, t.y, t.z, q.i, q.j, q.k, q.w
        ));
    }
    write_text(path, &text)
}

/// Writes an EuRoC-style csv (`#timestamp [ns],p_x,p_y,p_z,q_w,q_x,q_y,q_z`).
pub fn write_euroc(path: &Path, trajectory: &Trajectory) -> Result<()> {
    let mut text = String::from(
        "#timestamp [ns], p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z []\n",
    );
    for (stamp, pose) in trajectory.timestamps.iter().zip(&trajectory.poses) {
        let (t, q) = (translation(pose), pose.rotation);
        text.push_str(&format!(
            "{:.0},{:.9},{:.9},{:.9},{:.9},{:.9},{:.9},{:.9}\n",
            stamp * 1e9,
            t.x,
            t.y,
            t.z,
            q.w,
            q.i,
            q.j,
            q.k
        ));
    }
    write_text(path, &text)
}

/// Writes a trajectory in the given format.
pub fn write_trajectory(
    path: &Path,
    trajectory: &Trajectory,
    format: TrajectoryFormat,
) -> Result<()> {
    match format {
        TrajectoryFormat::Kitti => write_kitti(path, trajectory),
        TrajectoryFormat::Tum => write_tum(path, trajectory),
        TrajectoryFormat::Euroc => write_euroc(path, trajectory),
    }
}
