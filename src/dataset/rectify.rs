//! Stereo rectification of a calibrated, distorted camera pair (OpenCV
//! `stereoRectify` + `initUndistortRectifyMap` + `remap`).

use nalgebra::{Matrix3, Matrix4, Vector3};
use opencv::calib3d;
use opencv::core::{Mat, Rect, Scalar, Size, BORDER_CONSTANT, CV_32FC1};
use opencv::imgproc;
use opencv::prelude::*;

use super::error::{DatasetError, Result};
use super::euroc_camera::CameraCalibration;

/// A rectified left/right image pair.
#[derive(Debug)]
pub struct RectifiedPair {
    /// Rectified left image.
    pub left: Mat,
    /// Rectified right image.
    pub right: Mat,
}

/// Undistortion and rectification maps for both cameras, and the rectified
/// pinhole model shared by them (rows aligned, zero disparity at infinity).
#[derive(Debug)]
pub struct StereoRectifier {
    size: Size,
    left_maps: (Mat, Mat),
    right_maps: (Mat, Mat),
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    baseline: f64,
    left_rotation: Matrix3<f64>,
}

impl StereoRectifier {
    /// Builds the maps for EuRoC's `cam0` (left) and `cam1` (right).
    ///
    /// The relative pose is `T_c1_c0 = inv(T_BS1) · T_BS0`; rectification uses
    /// `CALIB_ZERO_DISPARITY` and alpha 0 (only valid pixels), keeping the
    /// input size.
    pub fn from_euroc(cam0: &CameraCalibration, cam1: &CameraCalibration) -> Result<Self> {
        if (cam0.width, cam0.height) != (cam1.width, cam1.height) {
            return Err(DatasetError::InvalidCalibration {
                reason: format!(
                    "cameras differ in size: {}x{} vs {}x{}",
                    cam0.width, cam0.height, cam1.width, cam1.height
                ),
            });
        }
        let size = Size::new(to_i32(cam0.width)?, to_i32(cam0.height)?);
        let t_bs1_inv =
            cam1.t_bs
                .try_inverse()
                .ok_or_else(|| DatasetError::InvalidCalibration {
                    reason: "cam1 T_BS is singular".into(),
                })?;
        let t_c1_c0: Matrix4<f64> = t_bs1_inv * cam0.t_bs;
        let r: Matrix3<f64> = t_c1_c0.fixed_view::<3, 3>(0, 0).into_owned();
        let t: Vector3<f64> = t_c1_c0.fixed_view::<3, 1>(0, 3).into_owned();

        let k0 = mat3(&cam0.camera_matrix())?;
        let k1 = mat3(&cam1.camera_matrix())?;
        let d0 = row(&cam0.distortion)?;
        let d1 = row(&cam1.distortion)?;
        let r_cv = mat3(&r)?;
        let t_cv =
            Mat::from_slice_2d(&[[t.x], [t.y], [t.z]]).map_err(DatasetError::cv("building T"))?;

        let (mut r0, mut r1, mut p0, mut p1, mut q) = (
            Mat::default(),
            Mat::default(),
            Mat::default(),
            Mat::default(),
            Mat::default(),
        );
        let (mut roi0, mut roi1) = (Rect::default(), Rect::default());
        calib3d::stereo_rectify(
            &k0,
            &d0,
            &k1,
            &d1,
            size,
            &r_cv,
            &t_cv,
            &mut r0,
            &mut r1,
            &mut p0,
            &mut p1,
            &mut q,
            calib3d::CALIB_ZERO_DISPARITY,
            0.0,
            size,
            Some(&mut roi0),
            Some(&mut roi1),
        )
        .map_err(DatasetError::cv("running stereoRectify"))?;

        let at = |m: &Mat, r: i32, c: i32| -> Result<f64> {
            m.at_2d::<f64>(r, c)
                .copied()
                .map_err(DatasetError::cv("reading the rectified projection"))
        };
        let fx = at(&p0, 0, 0)?;
        let baseline = -at(&p1, 0, 3)? / at(&p1, 0, 0)?;
        if !(baseline.is_finite() && baseline > 0.0) {
            return Err(DatasetError::InvalidCalibration {
                reason: format!(
                    "rectified baseline is {baseline} m; cam1 must be to the right of cam0"
                ),
            });
        }
        let mut left_rotation = Matrix3::zeros();
        for i in 0..3 {
            for j in 0..3 {
                left_rotation[(i, j)] = at(&r0, i as i32, j as i32)?;
            }
        }
        let left_maps = maps(&k0, &d0, &r0, &p0, size)?;
        let right_maps = maps(&k1, &d1, &r1, &p1, size)?;
        Ok(Self {
            size,
            left_maps,
            right_maps,
            fx,
            fy: at(&p0, 1, 1)?,
            cx: at(&p0, 0, 2)?,
            cy: at(&p0, 1, 2)?,
            baseline,
            left_rotation,
        })
    }

    /// OpenCV's `R1`: takes points in the raw left camera (`cam0`) to the
    /// rectified left camera (`p_rect = R1 · p_cam0`), to relate the
    /// rectified frames to the body frame of the ground truth.
    pub fn left_rotation(&self) -> Matrix3<f64> {
        self.left_rotation
    }

    /// Rectified focal length in x (pixels).
    pub fn fx(&self) -> f64 {
        self.fx
    }

    /// Rectified focal length in y (pixels).
    pub fn fy(&self) -> f64 {
        self.fy
    }

    /// Rectified principal point x (pixels), the same for both images.
    pub fn cx(&self) -> f64 {
        self.cx
    }

    /// Rectified principal point y (pixels), the same for both images.
    pub fn cy(&self) -> f64 {
        self.cy
    }

    /// Baseline in metres (positive: the right camera is to the right).
    pub fn baseline(&self) -> f64 {
        self.baseline
    }

    /// Image size `(width, height)` of inputs and outputs.
    pub fn image_size(&self) -> (i32, i32) {
        (self.size.width, self.size.height)
    }

    /// Undistorts and rectifies the left image alone (monocular runs).
    pub fn rectify_left(&self, left: &Mat) -> Result<Mat> {
        self.remap(left, &self.left_maps)
    }

    /// Undistorts and rectifies a pair (bilinear interpolation, black border).
    pub fn rectify(&self, left: &Mat, right: &Mat) -> Result<RectifiedPair> {
        Ok(RectifiedPair {
            left: self.remap(left, &self.left_maps)?,
            right: self.remap(right, &self.right_maps)?,
        })
    }

    fn remap(&self, image: &Mat, maps: &(Mat, Mat)) -> Result<Mat> {
        let got = image
            .size()
            .map_err(DatasetError::cv("reading the image size"))?;
        if got != self.size {
            return Err(DatasetError::ImageSizeMismatch {
                width: got.width,
                height: got.height,
                expected_width: self.size.width,
                expected_height: self.size.height,
            });
        }
        let mut out = Mat::default();
        imgproc::remap(
            image,
            &mut out,
            &maps.0,
            &maps.1,
            imgproc::INTER_LINEAR,
            BORDER_CONSTANT,
            Scalar::all(0.0),
        )
        .map_err(DatasetError::cv("remapping an image"))?;
        Ok(out)
    }
}

/// The undistort-rectify maps of one camera.
fn maps(k: &Mat, d: &Mat, r: &Mat, p: &Mat, size: Size) -> Result<(Mat, Mat)> {
    let (mut m1, mut m2) = (Mat::default(), Mat::default());
    calib3d::init_undistort_rectify_map(k, d, r, p, size, CV_32FC1, &mut m1, &mut m2)
        .map_err(DatasetError::cv("running initUndistortRectifyMap"))?;
    Ok((m1, m2))
}

fn mat3(m: &Matrix3<f64>) -> Result<Mat> {
    let rows = [
        [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
        [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
        [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
    ];
    Mat::from_slice_2d(&rows).map_err(DatasetError::cv("building a 3x3 matrix"))
}

fn row(values: &[f64; 4]) -> Result<Mat> {
    Mat::from_slice_2d(&[*values]).map_err(DatasetError::cv("building distortion coefficients"))
}

fn to_i32(v: u32) -> Result<i32> {
    i32::try_from(v).map_err(|_| DatasetError::InvalidCalibration {
        reason: format!("image side {v} is too large"),
    })
}
