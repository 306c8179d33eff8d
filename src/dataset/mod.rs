//! Dataset readers: KITTI odometry, EuRoC/ASL and TUM RGB-D folder layouts,
//! plus stereo rectification for EuRoC's distorted cameras, and a generator
//! of synthetic stereo/RGB-D sequences with exact ground truth ([`synthetic`]).
//!
//! Readers check the layout when opening and return typed [`DatasetError`]s
//! naming the offending path (and 1-based line for text files). They expose
//! image *paths*; decoding images and parsing ground-truth trajectories is
//! left to other modules.

mod associate;
mod error;
mod euroc;
mod euroc_camera;
mod euroc_csv;
mod kitti;
mod kitti_calib;
mod rectify;
pub mod synthetic;
mod text;
mod tum;
mod yaml;

use std::path::PathBuf;

pub use associate::{associate, Association};
pub use error::{DatasetError, Result};
pub use euroc::EurocSequence;
pub use euroc_camera::CameraCalibration;
pub use euroc_csv::ImuSample;
pub use kitti::KittiSequence;
pub use kitti_calib::KittiCalibration;
pub use rectify::{RectifiedPair, StereoRectifier};
pub use tum::{RgbdFrame, TumRgbdSequence, DEFAULT_MAX_DIFFERENCE};

/// One stereo frame: a timestamp and the paths of the left and right images.
#[derive(Debug, Clone, PartialEq)]
pub struct StereoFrame {
    /// Time in seconds (KITTI: from `times.txt`; EuRoC: nanoseconds / 1e9).
    pub timestamp: f64,
    /// Path of the left image.
    pub left: PathBuf,
    /// Path of the right image.
    pub right: PathBuf,
}
