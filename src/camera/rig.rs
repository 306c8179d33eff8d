//! The camera rig: one pinhole camera, and for stereo and RGB-D the
//! (virtual) baseline that turns depths into right-image columns.

use nalgebra::Vector3;

use super::Sensor;
use crate::geometry::two_view::PinholeIntrinsics;

use crate::optim::reprojection::PinholeStereo;
use crate::settings::SlamSettings;

/// The virtual baseline of an RGB-D camera whose settings give none
/// (metres): about a Kinect's projector-to-camera distance. ORB-SLAM3's
/// TUM settings use `Camera.bf: 40` (7.7 cm at fx 517). It only sets the
/// weight of the virtual right coordinate and the close-point distance.
pub const DEFAULT_RGBD_BASELINE: f64 = 0.08;

/// Camera intrinsics, sensor kind, baseline, image size and the depth limits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraRig {
    /// What the frames hold besides the (left) image.
    pub sensor: Sensor,
    /// The (left) camera with `bf` (0 for monocular).
    pub camera: PinholeStereo,
    /// Stereo baseline (RGB-D: the virtual one), metres; 0 for monocular.
    pub baseline: f64,
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// Stereo points closer than this are "close" (ORB-SLAM3's `mThDepth`), metres.
    pub close_depth: f64,
    /// Far keypoints count as stereo observations (`Stereo.farPointsStereo`;
    /// see [`stereo_depth_limit`](Self::stereo_depth_limit)).
    pub far_points_stereo: bool,
    /// Stereo depths beyond this are dropped at frame construction, metres.
    pub max_depth: Option<f64>,
    /// Frames per second (sets the keyframe and relocalisation windows).
    pub fps: f64,
}

/// Camera settings that cannot drive the SLAM system (the system reports it
/// as `SlamError::InvalidCamera`).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("invalid camera for stereo SLAM: {reason}")]
pub struct InvalidCamera {
    /// What is wrong.
    pub reason: String,
}

impl CameraRig {
    /// Keypoints with a depth below this count as stereo observations,
    /// the others with their bearing only (`map::observation`'s policy):
    /// the close depth, or no limit with `Stereo.farPointsStereo`.
    pub fn stereo_depth_limit(&self) -> f64 {
        if self.far_points_stereo {
            f64::INFINITY
        } else {
            self.close_depth
        }
    }

    /// The stereo rig described by `settings` for images of `width` x
    /// `height` (see [`Self::for_sensor`]).
    pub fn from_settings(
        settings: &SlamSettings,
        width: usize,
        height: usize,
    ) -> Result<Self, InvalidCamera> {
        Self::for_sensor(settings, Sensor::Stereo, width, height)
    }

    /// The rig of `sensor` described by `settings`, as ORB-SLAM3's
    /// `Tracking` reads them: stereo needs `Stereo.b` (or `Camera.bf`);
    /// RGB-D takes the same key as a virtual baseline
    /// ([`DEFAULT_RGBD_BASELINE`] without it); monocular ignores it.
    /// `ThDepth` times the baseline is the close-point distance.
    pub fn for_sensor(
        settings: &SlamSettings,
        sensor: Sensor,
        width: usize,
        height: usize,
    ) -> Result<Self, InvalidCamera> {
        let c = &settings.camera;
        let baseline = match sensor {
            Sensor::Monocular => 0.0,
            Sensor::Stereo => c.baseline.ok_or_else(|| InvalidCamera {
                reason: "the settings have no stereo baseline (Stereo.b or Camera.bf); \
                         use --sensor mono or rgbd for a single camera"
                    .into(),
            })?,
            Sensor::Rgbd => c.baseline.unwrap_or(DEFAULT_RGBD_BASELINE),
        };
        let camera = PinholeStereo::new(c.fx, c.fy, c.cx, c.cy, baseline * c.fx);
        let baseline_ok = baseline.is_finite() && (baseline > 0.0 || sensor == Sensor::Monocular);
        if !camera.is_valid() || !baseline_ok || width == 0 || height == 0 {
            return Err(InvalidCamera {
                reason: format!(
                    "{sensor}: fx {}, fy {}, cx {}, cy {}, baseline {baseline}, image {width}x{height}",
                    c.fx, c.fy, c.cx, c.cy
                ),
            });
        }
        let close_depth = match sensor {
            Sensor::Monocular => f64::INFINITY,
            _ => baseline * settings.th_depth,
        };
        Ok(Self {
            sensor,
            camera,
            baseline,
            width,
            height,
            close_depth,
            far_points_stereo: settings.far_points_stereo,
            max_depth: settings.max_depth.filter(|d| *d > 0.0),
            fps: if c.fps > 0.0 { c.fps } else { 10.0 },
        })
    }

    /// The (left) camera's intrinsics.
    pub fn intrinsics(&self) -> PinholeIntrinsics {
        PinholeIntrinsics {
            fx: self.camera.fx,
            fy: self.camera.fy,
            cx: self.camera.cx,
            cy: self.camera.cy,
        }
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

    /// The stereo projection `(u, v, u_right)` of the camera-frame point
    /// `pc` when it lies in front of the camera and inside the image.
    pub fn project_in_image(&self, pc: &Vector3<f64>) -> Option<Vector3<f64>> {
        if pc.z <= 0.0 {
            return None;
        }
        let uvr = self.camera.project_stereo(pc);
        self.contains(uvr.x, uvr.y).then_some(uvr)
    }
}
