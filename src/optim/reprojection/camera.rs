//! The rectified stereo pinhole camera used by the reprojection residuals.

use nalgebra::{Vector2, Vector3};

/// A rectified pinhole camera with an optional stereo baseline
/// (ORB-SLAM3's `fx, fy, cx, cy, bf`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PinholeStereo {
    /// Focal length in x (pixels).
    pub fx: f64,
    /// Focal length in y (pixels).
    pub fy: f64,
    /// Principal point x (pixels).
    pub cx: f64,
    /// Principal point y (pixels).
    pub cy: f64,
    /// `fx · baseline` (pixel·metres); 0 for a monocular camera.
    pub bf: f64,
}

impl PinholeStereo {
    /// A camera from its intrinsics and `bf = fx · baseline`.
    pub fn new(fx: f64, fy: f64, cx: f64, cy: f64, bf: f64) -> Self {
        Self { fx, fy, cx, cy, bf }
    }

    /// True when every parameter is finite, the focal lengths are positive
    /// and `bf` is not negative.
    pub fn is_valid(&self) -> bool {
        [self.fx, self.fy, self.cx, self.cy, self.bf]
            .iter()
            .all(|v| v.is_finite())
            && self.fx > 0.0
            && self.fy > 0.0
            && self.bf >= 0.0
    }

    /// The left-image pixel `(u, v)` of a point in camera coordinates.
    pub fn project(&self, p_cam: &Vector3<f64>) -> Vector2<f64> {
        let inv_z = 1.0 / p_cam.z;
        Vector2::new(
            self.fx * p_cam.x * inv_z + self.cx,
            self.fy * p_cam.y * inv_z + self.cy,
        )
    }

    /// The stereo measurement `(u, v, u_right)` with `u_right = u − bf / z`.
    pub fn project_stereo(&self, p_cam: &Vector3<f64>) -> Vector3<f64> {
        let uv = self.project(p_cam);
        Vector3::new(uv.x, uv.y, uv.x - self.bf / p_cam.z)
    }
}
