//! The rectified stereo rig.

use nalgebra::Vector3;

use crate::error::SlamError;
use crate::optim::reprojection::PinholeStereo;
use crate::settings::SlamSettings;

/// Camera intrinsics, baseline, image size and the depth limits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StereoRig {
    /// The left camera with `bf`.
    pub camera: PinholeStereo,
    /// Stereo baseline, metres.
    pub baseline: f64,
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// Stereo points closer than this are "close" (ORB-SLAM3's `mThDepth`), metres.
    pub close_depth: f64,
    /// Stereo depths beyond this are dropped at frame construction, metres.
    pub max_depth: Option<f64>,
    /// Frames per second (sets the keyframe and relocalisation windows).
    pub fps: f64,
}

impl StereoRig {
    /// The rig described by `settings` for images of `width` x `height`.
    pub fn from_settings(
        settings: &SlamSettings,
        width: usize,
        height: usize,
    ) -> Result<Self, SlamError> {
        let c = &settings.camera;
        let baseline = c.baseline.ok_or_else(|| SlamError::InvalidCamera {
            reason: "the settings have no stereo baseline (Stereo.b)".into(),
        })?;
        let camera = PinholeStereo::new(c.fx, c.fy, c.cx, c.cy, baseline * c.fx);
        if !camera.is_valid() || baseline.is_nan() || baseline <= 0.0 {
            return Err(SlamError::InvalidCamera {
                reason: format!(
                    "fx {}, fy {}, cx {}, cy {}, baseline {baseline}",
                    c.fx, c.fy, c.cx, c.cy
                ),
            });
        }
        Ok(Self {
            camera,
            baseline,
            width,
            height,
            close_depth: settings.close_depth().unwrap_or(40.0 * baseline),
            max_depth: settings.max_depth.filter(|d| *d > 0.0),
            fps: if c.fps > 0.0 { c.fps } else { 10.0 },
        })
    }

    /// The camera-frame point seen at pixel `(u, v)` with depth `z`.
    pub fn unproject(&self, u: f64, v: f64, z: f64) -> Vector3<f64> {
        Vector3::new(
            (u - self.camera.cx) * z / self.camera.fx,
            (v - self.camera.cy) * z / self.camera.fy,
            z,
        )
    }

    /// True when the pixel lies inside the image.
    pub fn contains(&self, u: f64, v: f64) -> bool {
        u >= 0.0 && v >= 0.0 && u < self.width as f64 && v < self.height as f64
    }
}
