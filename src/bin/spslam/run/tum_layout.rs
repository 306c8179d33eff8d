//! A TUM RGB-D folder for `spslam run`: `rgb.txt` and `depth.txt`
//! associated by timestamp (`associate.py`'s 0.02 s), `groundtruth.txt`
//! when present, and the camera from `--settings`, or from a KITTI
//! `calib.txt` beside the lists (as `spslam synth` writes).

use std::path::{Path, PathBuf};

use anyhow::Result;
use spslam::dataset::{
    KittiCalibration, RgbdFrame, TumRgbdSequence, DEFAULT_MAX_DIFFERENCE as TUM_MAX_DIFFERENCE,
};

/// A TUM RGB-D sequence: its associated frames, camera and ground truth.
pub struct TumLayout {
    /// Colour/depth pairs in time order.
    pub frames: Vec<RgbdFrame>,
    /// `calib.txt` beside the lists (`spslam synth` output), if any.
    pub calibration: Option<KittiCalibration>,
    /// `groundtruth.txt`, when it exists.
    pub ground_truth: Option<PathBuf>,
}

impl TumLayout {
    /// Opens a TUM RGB-D folder.
    pub fn open(dir: &Path) -> Result<Self> {
        let seq = TumRgbdSequence::open(dir, TUM_MAX_DIFFERENCE)?;
        if seq.unmatched_rgb() > 0 {
            eprintln!(
                "warning: {} colour images have no depth image within {TUM_MAX_DIFFERENCE} s and are left out",
                seq.unmatched_rgb()
            );
        }
        let calib = dir.join("calib.txt");
        let calibration = if calib.is_file() {
            Some(KittiCalibration::from_file(&calib)?)
        } else {
            None
        };
        Ok(Self {
            frames: seq.frames().to_vec(),
            calibration,
            ground_truth: seq.ground_truth_path(),
        })
    }
}
