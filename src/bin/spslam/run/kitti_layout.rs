//! A KITTI-layout sequence (KITTI odometry or `spslam synth`) for
//! `spslam run`, which must survive missing images: the library's
//! [`KittiSequence`] refuses a sequence whose cameras count different
//! images, so then the frames are named from `times.txt` the way KITTI
//! (and ORB-SLAM3's loader) names them, `image_0/%06d.png`, and a missing
//! image is skipped as unreadable when its frame comes.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use spslam::dataset::{DatasetError, KittiCalibration, KittiSequence, StereoFrame};

/// A KITTI-layout sequence: its calibration, frames and ground truth.
pub struct KittiLayout {
    /// `calib.txt`.
    pub calibration: KittiCalibration,
    /// One frame per row of `times.txt`.
    pub frames: Vec<StereoFrame>,
    /// `poses/NN.txt` beside `sequences/`, when it exists.
    pub ground_truth: Option<PathBuf>,
    /// The sequence has no `image_1/` (a left-camera-only excerpt such as
    /// the shared KITTI 07): monocular runs only.
    pub left_only: bool,
}

impl KittiLayout {
    /// Opens a sequence from its own folder or a root holding `sequences/`
    /// (the first sequence with a `calib.txt`).
    pub fn open(dir: &Path) -> Result<Self> {
        let (root, name) = if dir.join("calib.txt").is_file() {
            let name = dir.file_name().and_then(|n| n.to_str()).unwrap_or("00");
            (dir.to_path_buf(), name.to_string())
        } else {
            (dir.to_path_buf(), first_sequence(dir)?)
        };
        let sequence_dir = if root.join("calib.txt").is_file() {
            root.clone()
        } else {
            root.join("sequences").join(&name)
        };
        if sequence_dir.join("image_0").is_dir() && !sequence_dir.join("image_1").exists() {
            // Left camera only: the frames are named from times.txt.
            return Self::named_from_times(&sequence_dir).map(|layout| Self {
                left_only: true,
                ..layout
            });
        }
        match KittiSequence::open(&root, &name) {
            Ok(seq) => Ok(Self {
                calibration: seq.calibration().clone(),
                frames: seq.frames().to_vec(),
                ground_truth: seq.ground_truth_path(),
                left_only: false,
            }),
            Err(
                e @ (DatasetError::ImageCountMismatch { .. }
                | DatasetError::TimestampCountMismatch { .. }),
            ) => {
                eprintln!(
                    "warning: {e}; the frames are named from times.txt (image_0/%06d.png), \
                     and missing images are skipped as unreadable"
                );
                Self::named_from_times(&sequence_dir)
            }
            Err(e) => Err(e.into()),
        }
    }

    /// The frames of `times.txt`, named `image_0/%06d.png` and
    /// `image_1/%06d.png` whether or not the files exist.
    fn named_from_times(sequence: &Path) -> Result<Self> {
        let calibration = KittiCalibration::from_file(&sequence.join("calib.txt"))?;
        let times_path = sequence.join("times.txt");
        let text = std::fs::read_to_string(&times_path)
            .with_context(|| format!("cannot read {}", times_path.display()))?;
        let mut frames = Vec::new();
        for (number, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let timestamp: f64 = line.parse().with_context(|| {
                format!(
                    "{}:{}: `{line}` is not a timestamp",
                    times_path.display(),
                    number + 1
                )
            })?;
            let file = format!("{:06}.png", frames.len());
            frames.push(StereoFrame {
                timestamp,
                left: sequence.join("image_0").join(&file),
                right: sequence.join("image_1").join(&file),
            });
        }
        if frames.is_empty() {
            bail!("{} lists no frame", times_path.display());
        }
        Ok(Self {
            calibration,
            frames,
            ground_truth: ground_truth_beside(sequence),
            left_only: false,
        })
    }
}

/// The first sequence (by name) under `dir/sequences` that has a `calib.txt`.
fn first_sequence(dir: &Path) -> Result<String> {
    let sequences = dir.join("sequences");
    let mut names: Vec<String> = std::fs::read_dir(&sequences)
        .with_context(|| format!("{} has no calib.txt nor sequences/", dir.display()))?
        .filter_map(|e| e.ok())
        .filter(|e| e.path().join("calib.txt").is_file())
        .filter_map(|e| e.file_name().to_str().map(String::from))
        .collect();
    names.sort();
    match names.into_iter().next() {
        Some(name) => Ok(name),
        None => bail!("no sequence with a calib.txt under {}", sequences.display()),
    }
}

/// `<root>/poses/NN.txt` for `<root>/sequences/NN`, when it exists.
fn ground_truth_beside(sequence: &Path) -> Option<PathBuf> {
    let name = sequence.file_name()?;
    let root = sequence.parent()?.parent()?;
    let path = root.join("poses").join(name).with_extension("txt");
    path.is_file().then_some(path)
}
