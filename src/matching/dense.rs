//! A dense disparity reference (OpenCV's semi-global block matching) to check
//! sparse stereo matches against.

use opencv::core::Mat;
use opencv::prelude::*;

use super::MatchError;
use crate::features::GrayImageView;

/// A dense disparity map, level-0 pixels; invalid pixels are `None`.
#[derive(Clone, Debug, PartialEq)]
pub struct DisparityMap {
    width: usize,
    height: usize,
    /// Disparity x 16 as OpenCV returns it; negative = invalid.
    fixed: Vec<i16>,
}

impl DisparityMap {
    /// The disparity at the nearest pixel, or `None` when invalid or outside.
    pub fn at(&self, x: f32, y: f32) -> Option<f32> {
        let (xi, yi) = (x.round(), y.round());
        if xi < 0.0 || yi < 0.0 || xi as usize >= self.width || yi as usize >= self.height {
            return None;
        }
        let v = self.fixed[yi as usize * self.width + xi as usize];
        (v >= 0).then(|| v as f32 / 16.0)
    }

    /// Share of valid pixels.
    pub fn valid_fraction(&self) -> f32 {
        self.fixed.iter().filter(|&&v| v >= 0).count() as f32 / self.fixed.len().max(1) as f32
    }
}

/// StereoSGBM (5x5 blocks, P1 = 8·25, P2 = 32·25, uniqueness 10, left-right
/// check 1 px, speckle filter) over `max_disparity` (rounded up to a multiple of 16).
pub fn sgbm_disparity(
    left: GrayImageView<'_>,
    right: GrayImageView<'_>,
    max_disparity: usize,
) -> Result<DisparityMap, MatchError> {
    if (left.width(), left.height()) != (right.width(), right.height()) {
        return Err(MatchError::ImageSizeMismatch {
            left_width: left.width(),
            left_height: left.height(),
            right_width: right.width(),
            right_height: right.height(),
        });
    }
    let num = max_disparity.div_ceil(16).max(1) * 16;
    let block = 5;
    let mut sgbm = opencv::calib3d::StereoSGBM::create(
        0,
        num as i32,
        block,
        8 * block * block,
        32 * block * block,
        1,
        63,
        10,
        100,
        2,
        opencv::calib3d::StereoSGBM_MODE_SGBM,
    )?;
    let l = left.to_owned_image().to_mat()?;
    let r = right.to_owned_image().to_mat()?;
    let mut disparity = Mat::default();
    sgbm.compute(&l, &r, &mut disparity)?;
    let fixed: Vec<i16> = disparity.data_typed::<i16>()?.to_vec();
    Ok(DisparityMap {
        width: left.width(),
        height: left.height(),
        fixed,
    })
}
