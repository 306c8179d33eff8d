//! KITTI odometry sequences: `sequences/XX/{image_0,image_1,calib.txt,times.txt}`
//! and ground truth in `poses/XX.txt`.

use std::path::{Path, PathBuf};

use super::error::{DatasetError, Result};
use super::kitti_calib::KittiCalibration;
use super::text::{data_lines, parse_f64, read_text, require_dir, require_increasing};
use super::StereoFrame;

/// A KITTI odometry stereo sequence, checked on opening.
#[derive(Debug, Clone)]
pub struct KittiSequence {
    dir: PathBuf,
    calibration: KittiCalibration,
    frames: Vec<StereoFrame>,
    ground_truth: Option<PathBuf>,
}

impl KittiSequence {
    /// Opens sequence `sequence` (e.g. `"06"`).
    ///
    /// `path` may be the sequence folder itself (holding `calib.txt`), the
    /// `sequences` folder, or the dataset root holding `sequences/`.
    /// Checks that the folders exist, that `calib.txt` is well formed, and
    /// that both cameras and `times.txt` count the same frames.
    pub fn open(path: impl AsRef<Path>, sequence: &str) -> Result<Self> {
        let dir = resolve_dir(path.as_ref(), sequence)?;
        let calibration = KittiCalibration::from_file(&dir.join("calib.txt"))?;
        let left_dir = require_dir(&dir.join("image_0"))?;
        let right_dir = require_dir(&dir.join("image_1"))?;
        let left = list_pngs(&left_dir)?;
        let right = list_pngs(&right_dir)?;
        if left.len() != right.len() {
            return Err(DatasetError::ImageCountMismatch {
                left_dir,
                left: left.len(),
                right_dir,
                right: right.len(),
            });
        }
        let times_path = dir.join("times.txt");
        let times = read_times(&times_path)?;
        if times.len() != left.len() {
            return Err(DatasetError::TimestampCountMismatch {
                path: times_path,
                timestamps: times.len(),
                images: left.len(),
            });
        }
        if left.is_empty() {
            return Err(DatasetError::NoFrames { path: dir });
        }
        let frames = times
            .into_iter()
            .zip(left.into_iter().zip(right))
            .map(|(timestamp, (left, right))| StereoFrame {
                timestamp,
                left,
                right,
            })
            .collect();
        let ground_truth = ground_truth_beside(&dir);
        Ok(Self {
            dir,
            calibration,
            frames,
            ground_truth,
        })
    }

    /// The sequence folder (`…/sequences/XX`).
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The calibration read from `calib.txt`.
    pub fn calibration(&self) -> &KittiCalibration {
        &self.calibration
    }

    /// The stereo frames in time order (timestamps in seconds from `times.txt`).
    pub fn frames(&self) -> &[StereoFrame] {
        &self.frames
    }

    /// `poses/XX.txt` beside `sequences/`, when it exists.
    pub fn ground_truth_path(&self) -> Option<PathBuf> {
        self.ground_truth.clone()
    }
}

/// Finds the sequence folder from any of the accepted starting points.
fn resolve_dir(path: &Path, sequence: &str) -> Result<PathBuf> {
    if !path.is_dir() {
        return Err(DatasetError::MissingFolder {
            path: path.to_path_buf(),
        });
    }
    if path.join("calib.txt").is_file() {
        return Ok(path.to_path_buf());
    }
    for candidate in [path.join("sequences").join(sequence), path.join(sequence)] {
        if candidate.is_dir() {
            return Ok(candidate);
        }
    }
    // The most likely intended layout, for the error message.
    let expected = if path.join("sequences").is_dir() || path.ends_with("sequences") {
        path.join("sequences").join(sequence)
    } else {
        path.join(sequence)
    };
    Err(DatasetError::MissingFolder { path: expected })
}

/// The PNG files of a folder, sorted by name.
fn list_pngs(dir: &Path) -> Result<Vec<PathBuf>> {
    let io = |source| DatasetError::Io {
        path: dir.to_path_buf(),
        source,
    };
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(io)? {
        let path = entry.map_err(io)?.path();
        if path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("png"))
        {
            files.push(path);
        }
    }
    files.sort();
    Ok(files)
}

/// `times.txt`: one timestamp in seconds per row, strictly increasing.
fn read_times(path: &Path) -> Result<Vec<f64>> {
    let text = read_text(path)?;
    let mut times: Vec<f64> = Vec::new();
    for line in data_lines(&text) {
        let t = parse_f64(path, line.number, "timestamp", line.text)?;
        require_increasing(path, line.number, times.last().copied(), t)?;
        times.push(t);
    }
    Ok(times)
}

/// `<root>/poses/XX.txt` for `<root>/sequences/XX`.
fn ground_truth_beside(dir: &Path) -> Option<PathBuf> {
    let name = dir.file_name()?;
    let root = dir.parent()?.parent()?;
    let path = root.join("poses").join(name).with_extension("txt");
    path.is_file().then_some(path)
}
