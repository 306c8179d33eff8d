//! The camera rig as tracking and local mapping see it: intrinsics, stereo
//! baseline, image size, ORB-SLAM3's close/far depth threshold and the
//! optional depth filter. It sits below tracking and mapping, so both can
//! use it without importing each other.

mod depth;
mod rig;
mod sensor;

pub use depth::{DepthError, DepthImage};
pub use rig::{CameraRig, InvalidCamera, DEFAULT_RGBD_BASELINE};
pub use sensor::{Sensor, UnknownSensor};
