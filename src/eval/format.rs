//! Trajectory file formats and their detection.

use std::path::Path;
use std::str::FromStr;

use super::error::{EvalError, Result};

/// The supported trajectory file formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum TrajectoryFormat {
    /// KITTI odometry: 12 numbers a line, the row-major 3×4 pose matrix.
    Kitti,
    /// TUM RGB-D: `t tx ty tz qx qy qz qw`, `#` comments.
    Tum,
    /// EuRoC ground-truth csv: `timestamp[ns], px, py, pz, qw, qx, qy, qz, …`.
    Euroc,
}

impl FromStr for TrajectoryFormat {
    type Err = EvalError;

    fn from_str(s: &str) -> Result<Self> {
        match s.trim().to_ascii_lowercase().as_str() {
            "kitti" => Ok(Self::Kitti),
            "tum" => Ok(Self::Tum),
            "euroc" => Ok(Self::Euroc),
            _ => Err(EvalError::UnknownFormat {
                name: s.to_string(),
            }),
        }
    }
}

impl std::fmt::Display for TrajectoryFormat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Kitti => "kitti",
            Self::Tum => "tum",
            Self::Euroc => "euroc",
        })
    }
}

impl TrajectoryFormat {
    /// Detects the format: a `.csv` file is EuRoC; otherwise the first data
    /// row (skipping blank and `#` lines) with 12 numbers is KITTI, 8 is TUM.
    pub fn detect(path: &Path) -> Result<Self> {
        let is_csv = path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| e.eq_ignore_ascii_case("csv"));
        if is_csv {
            return Ok(Self::Euroc);
        }
        let text = std::fs::read_to_string(path).map_err(|source| EvalError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let columns = text
            .lines()
            .map(str::trim)
            .find(|l| !l.is_empty() && !l.starts_with('#'))
            .map(|l| l.split([' ', '\t', ',']).filter(|t| !t.is_empty()).count())
            .ok_or_else(|| EvalError::Empty {
                path: path.to_path_buf(),
            })?;
        match columns {
            12 => Ok(Self::Kitti),
            8 => Ok(Self::Tum),
            _ => Err(EvalError::UndetectedFormat {
                path: path.to_path_buf(),
                columns,
            }),
        }
    }
}
