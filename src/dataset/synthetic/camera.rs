//! The rectified stereo pinhole camera (KITTI convention: x right, y down,
//! z forward; the right camera sits `baseline` metres along the left's x).

use nalgebra::{Isometry3, Matrix3, Point2, Point3, Translation3, UnitQuaternion, Vector3};

/// A rectified stereo pair of identical pinhole cameras.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StereoCamera {
    /// Image width (pixels).
    pub width: usize,
    /// Image height (pixels).
    pub height: usize,
    /// Focal length in x (pixels).
    pub fx: f64,
    /// Focal length in y (pixels).
    pub fy: f64,
    /// Principal point x (pixels; pixel centres lie on integers).
    pub cx: f64,
    /// Principal point y (pixels).
    pub cy: f64,
    /// Distance between the optical centres (metres).
    pub baseline: f64,
    /// The right camera's turn about its y axis (radians) that the
    /// calibration does not know of: a negative turn (towards the left
    /// camera) makes every disparity read `fx · tan(−yaw)` pixels short at
    /// the image centre (and up to 1.6 times that at the sides of a 77°
    /// view). 0 for an exact rig.
    pub right_yaw: f64,
}

impl StereoCamera {
    /// Square pixels, principal point at the image centre.
    pub fn centred(width: usize, height: usize, focal_length: f64, baseline: f64) -> Self {
        Self {
            width,
            height,
            fx: focal_length,
            fy: focal_length,
            cx: (width as f64 - 1.0) / 2.0,
            cy: (height as f64 - 1.0) / 2.0,
            baseline,
            right_yaw: 0.0,
        }
    }

    /// The same pair with the right camera turned so that disparities read
    /// `offset` pixels short (see [`right_yaw`](Self::right_yaw)).
    pub fn with_disparity_offset(mut self, offset: f64) -> Self {
        self.right_yaw = -(offset / self.fx).atan();
        self
    }

    /// The intrinsic matrix K.
    pub fn k(&self) -> Matrix3<f64> {
        Matrix3::new(self.fx, 0.0, self.cx, 0.0, self.fy, self.cy, 0.0, 0.0, 1.0)
    }

    /// Projects a point given in a camera's frame to pixels (`None` behind it).
    pub fn project(&self, point_in_camera: &Point3<f64>) -> Option<Point2<f64>> {
        let p = point_in_camera;
        (p.z > 0.0)
            .then(|| Point2::new(self.fx * p.x / p.z + self.cx, self.fy * p.y / p.z + self.cy))
    }

    /// The pose of the right camera in the left camera's frame (T_left_right).
    pub fn right_in_left(&self) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(self.baseline, 0.0, 0.0),
            UnitQuaternion::from_axis_angle(&Vector3::y_axis(), self.right_yaw),
        )
    }

    /// The right camera's pose T_wc given the left's.
    pub fn right_pose(&self, left_pose: &Isometry3<f64>) -> Isometry3<f64> {
        left_pose * self.right_in_left()
    }

    /// The viewing ray of pixel `(x, y)` in the camera frame, scaled so that z = 1.
    pub fn ray(&self, x: f64, y: f64) -> Vector3<f64> {
        Vector3::new((x - self.cx) / self.fx, (y - self.cy) / self.fy, 1.0)
    }

    /// KITTI's projection matrices P0 (left) and P1 (right), row-major 3×4.
    pub fn kitti_projections(&self) -> [[f64; 12]; 2] {
        let p0 = [
            self.fx, 0.0, self.cx, 0.0, 0.0, self.fy, self.cy, 0.0, 0.0, 0.0, 1.0, 0.0,
        ];
        let mut p1 = p0;
        p1[3] = -self.fx * self.baseline;
        [p0, p1]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_point_projects_with_the_disparity_f_b_over_z() {
        let cam = StereoCamera::centred(640, 480, 400.0, 0.5);
        let left = Isometry3::identity();
        let x = Point3::new(1.0, -0.5, 8.0);
        let pl = cam.project(&(left.inverse() * x)).unwrap();
        let pr = cam.project(&(cam.right_pose(&left).inverse() * x)).unwrap();
        assert!((pl.y - pr.y).abs() < 1e-12);
        assert!((pl.x - pr.x - 400.0 * 0.5 / 8.0).abs() < 1e-12);
        assert!(cam.project(&Point3::new(0.0, 0.0, -1.0)).is_none());
    }

    /// At the principal point the offset is exact; off-centre a turn shifts
    /// by `offset · (1 + tan²α)`, α the point's angle from the right
    /// camera's axis.
    #[test]
    fn a_turned_right_camera_shortens_every_disparity_by_the_offset() {
        let cam = StereoCamera::centred(640, 480, 400.0, 0.5).with_disparity_offset(0.1);
        let left = Isometry3::identity();
        for (x, y, z) in [(0.0, 0.0, 40.0), (10.0, -3.0, 30.0), (-2.0, 1.0, 6.0)] {
            let p = Point3::new(x, y, z);
            let pl = cam.project(&p).unwrap();
            let pr = cam.project(&(cam.right_pose(&left).inverse() * p)).unwrap();
            let short = 400.0 * 0.5 / z - (pl.x - pr.x);
            let tan = (pr.x - cam.cx) / cam.fx;
            let expected = 0.1 * (1.0 + tan * tan);
            assert!(
                (short - expected).abs() < 0.01 * expected,
                "{x},{y},{z}: {short}"
            );
        }
    }

    #[test]
    fn kitti_p1_holds_minus_f_b() {
        let cam = StereoCamera::centred(640, 480, 400.0, 0.5);
        let [p0, p1] = cam.kitti_projections();
        assert_eq!(p0[3], 0.0);
        assert_eq!(p1[3], -200.0);
        assert_eq!(p0[2], 319.5);
    }
}
