//! A EuRoC/ASL sequence for `spslam run`, which must survive missing
//! images: the library's [`EurocSequence`] refuses a sequence whose
//! `data.csv` lists an image that is not there, so then the frames are
//! read from the `data.csv` lists as they are, and a missing image is
//! skipped as unreadable when its frame comes.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use spslam::dataset::{
    CameraCalibration, DatasetError, EurocSequence, StereoFrame, StereoRectifier,
};

/// A EuRoC sequence: its frames, its rectification and its ground truth.
pub struct EurocLayout {
    /// Stereo pairs with equal timestamps, in time order.
    pub frames: Vec<StereoFrame>,
    /// Undistortion and rectification from the cameras' `sensor.yaml`.
    pub rectifier: StereoRectifier,
    /// `state_groundtruth_estimate0/data.csv`, when it exists.
    pub ground_truth: Option<PathBuf>,
}

impl EurocLayout {
    /// Opens a sequence from its `mav0` folder or the folder holding `mav0`.
    pub fn open(dir: &Path) -> Result<Self> {
        match EurocSequence::open(dir) {
            Ok(seq) => Ok(Self {
                rectifier: StereoRectifier::from_euroc(seq.cam0(), seq.cam1())?,
                frames: seq.frames().to_vec(),
                ground_truth: seq.ground_truth_path(),
            }),
            Err(e @ DatasetError::MissingFile { .. }) => {
                eprintln!(
                    "warning: {e}; the frames are read from the data.csv lists, \
                     and missing images are skipped as unreadable"
                );
                Self::listed(dir)
            }
            Err(e) => Err(e.into()),
        }
    }

    /// The frames of the `data.csv` lists, whether or not the files exist.
    fn listed(dir: &Path) -> Result<Self> {
        let mav0 = if dir.join("mav0").is_dir() {
            dir.join("mav0")
        } else {
            dir.to_path_buf()
        };
        let cam0 = CameraCalibration::from_sensor_yaml(&mav0.join("cam0/sensor.yaml"))?;
        let cam1 = CameraCalibration::from_sensor_yaml(&mav0.join("cam1/sensor.yaml"))?;
        let left = image_list(&mav0.join("cam0"))?;
        let right = image_list(&mav0.join("cam1"))?;
        let frames = pair_by_timestamp(&left, &right);
        if frames.is_empty() {
            bail!("no stereo pair in {}", mav0.display());
        }
        let gt = mav0.join("state_groundtruth_estimate0/data.csv");
        Ok(Self {
            frames,
            rectifier: StereoRectifier::from_euroc(&cam0, &cam1)?,
            ground_truth: gt.is_file().then_some(gt),
        })
    }
}

/// `(timestamp ns, image path)` of a camera's `data.csv`, sorted by time.
fn image_list(camera: &Path) -> Result<Vec<(u64, PathBuf)>> {
    let csv = camera.join("data.csv");
    let text =
        std::fs::read_to_string(&csv).with_context(|| format!("cannot read {}", csv.display()))?;
    let mut images = Vec::new();
    for (number, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let Some((t, name)) = line.split_once(',') else {
            bail!(
                "{}:{}: expected `timestamp, filename`",
                csv.display(),
                number + 1
            );
        };
        let t: u64 = t.trim().parse().with_context(|| {
            format!("{}:{}: `{t}` is not a timestamp", csv.display(), number + 1)
        })?;
        images.push((t, camera.join("data").join(name.trim())));
    }
    images.sort_by_key(|(t, _)| *t);
    Ok(images)
}

/// Stereo frames of the images with equal timestamps.
fn pair_by_timestamp(left: &[(u64, PathBuf)], right: &[(u64, PathBuf)]) -> Vec<StereoFrame> {
    let (mut i, mut j) = (0, 0);
    let mut frames = Vec::new();
    while let (Some((tl, l)), Some((tr, r))) = (left.get(i), right.get(j)) {
        match tl.cmp(tr) {
            std::cmp::Ordering::Less => i += 1,
            std::cmp::Ordering::Greater => j += 1,
            std::cmp::Ordering::Equal => {
                frames.push(StereoFrame {
                    // Split to keep the sub-second part exact.
                    timestamp: (tl / 1_000_000_000) as f64 + (tl % 1_000_000_000) as f64 * 1e-9,
                    left: l.clone(),
                    right: r.clone(),
                });
                i += 1;
                j += 1;
            }
        }
    }
    frames
}
