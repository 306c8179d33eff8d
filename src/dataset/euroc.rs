//! EuRoC/ASL sequences: `mav0/{cam0,cam1}/{data.csv,data/,sensor.yaml}`,
//! `imu0/data.csv` and `state_groundtruth_estimate0/data.csv`.

use std::path::{Path, PathBuf};

use super::error::{DatasetError, Result};
use super::euroc_camera::CameraCalibration;
use super::euroc_csv::{read_image_list, read_imu, CameraImage, ImuSample};
use super::text::{ns_to_s, require_dir};
use super::StereoFrame;

/// A EuRoC stereo-inertial sequence, checked on opening.
#[derive(Debug, Clone)]
pub struct EurocSequence {
    dir: PathBuf,
    cam0: CameraCalibration,
    cam1: CameraCalibration,
    frames: Vec<StereoFrame>,
    frame_ns: Vec<u64>,
    unmatched_left: Vec<u64>,
    unmatched_right: Vec<u64>,
    imu: Vec<ImuSample>,
    ground_truth: Option<PathBuf>,
}

impl EurocSequence {
    /// Opens a sequence from its `mav0` folder or the folder holding `mav0`.
    ///
    /// Stereo pairs are matched by exact timestamp; images of one camera
    /// with no partner are kept aside ([`unmatched_left`](Self::unmatched_left),
    /// [`unmatched_right`](Self::unmatched_right)). `imu0` is optional (empty
    /// samples when absent).
    pub fn open(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let dir = if path.join("mav0").is_dir() {
            path.join("mav0")
        } else {
            require_dir(path)?
        };
        let cam0_dir = require_dir(&dir.join("cam0"))?;
        let cam1_dir = require_dir(&dir.join("cam1"))?;
        let cam0 = CameraCalibration::from_sensor_yaml(&cam0_dir.join("sensor.yaml"))?;
        let cam1 = CameraCalibration::from_sensor_yaml(&cam1_dir.join("sensor.yaml"))?;
        let left = read_camera(&cam0_dir)?;
        let right = read_camera(&cam1_dir)?;
        let pairs = match_by_timestamp(left, right);
        if pairs.frames.is_empty() {
            return Err(DatasetError::NoFrames { path: dir });
        }
        if !pairs.unmatched_left.is_empty() || !pairs.unmatched_right.is_empty() {
            tracing::warn!(
                left = pairs.unmatched_left.len(),
                right = pairs.unmatched_right.len(),
                "EuRoC images without a stereo partner were skipped"
            );
        }
        let imu_csv = dir.join("imu0").join("data.csv");
        let imu = if imu_csv.is_file() {
            read_imu(&imu_csv)?
        } else {
            Vec::new()
        };
        let gt = dir.join("state_groundtruth_estimate0").join("data.csv");
        let ground_truth = gt.is_file().then_some(gt);
        Ok(Self {
            dir,
            cam0,
            cam1,
            frame_ns: pairs.frame_ns,
            frames: pairs.frames,
            unmatched_left: pairs.unmatched_left,
            unmatched_right: pairs.unmatched_right,
            imu,
            ground_truth,
        })
    }

    /// The `mav0` folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Calibration of the left camera (`cam0`).
    pub fn cam0(&self) -> &CameraCalibration {
        &self.cam0
    }

    /// Calibration of the right camera (`cam1`).
    pub fn cam1(&self) -> &CameraCalibration {
        &self.cam1
    }

    /// Stereo pairs in time order (timestamps in seconds).
    pub fn frames(&self) -> &[StereoFrame] {
        &self.frames
    }

    /// The exact nanosecond timestamps of [`frames`](Self::frames).
    pub fn frame_timestamps_ns(&self) -> &[u64] {
        &self.frame_ns
    }

    /// Timestamps (ns) of `cam0` images with no `cam1` image at the same time.
    pub fn unmatched_left(&self) -> &[u64] {
        &self.unmatched_left
    }

    /// Timestamps (ns) of `cam1` images with no `cam0` image at the same time.
    pub fn unmatched_right(&self) -> &[u64] {
        &self.unmatched_right
    }

    /// IMU samples in time order (empty when `imu0/data.csv` is absent).
    pub fn imu(&self) -> &[ImuSample] {
        &self.imu
    }

    /// `state_groundtruth_estimate0/data.csv`, when it exists.
    pub fn ground_truth_path(&self) -> Option<PathBuf> {
        self.ground_truth.clone()
    }
}

/// The image list of one camera folder.
fn read_camera(cam_dir: &Path) -> Result<Vec<CameraImage>> {
    let image_dir = require_dir(&cam_dir.join("data"))?;
    read_image_list(&cam_dir.join("data.csv"), &image_dir)
}

/// Stereo pairs and leftovers of an exact-timestamp merge.
struct Matched {
    frames: Vec<StereoFrame>,
    frame_ns: Vec<u64>,
    unmatched_left: Vec<u64>,
    unmatched_right: Vec<u64>,
}

/// Merges two time-sorted image lists on equal timestamps.
fn match_by_timestamp(left: Vec<CameraImage>, right: Vec<CameraImage>) -> Matched {
    let mut out = Matched {
        frames: Vec::new(),
        frame_ns: Vec::new(),
        unmatched_left: Vec::new(),
        unmatched_right: Vec::new(),
    };
    let mut right = right.into_iter().peekable();
    for l in left {
        while let Some(r) = right.next_if(|r| r.t_ns < l.t_ns) {
            out.unmatched_right.push(r.t_ns);
        }
        match right.next_if(|r| r.t_ns == l.t_ns) {
            Some(r) => {
                out.frames.push(StereoFrame {
                    timestamp: ns_to_s(l.t_ns),
                    left: l.path,
                    right: r.path,
                });
                out.frame_ns.push(l.t_ns);
            }
            None => out.unmatched_left.push(l.t_ns),
        }
    }
    out.unmatched_right.extend(right.map(|r| r.t_ns));
    out
}
