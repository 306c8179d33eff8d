//! rBRIEF descriptors through OpenCV's `ORB::compute` on given keypoints: it
//! blurs each level (7x7 Gaussian, sigma 2, as ORB-SLAM3) and applies the
//! same 256-pair pattern steered by the keypoint's angle.

use opencv::core::{KeyPoint, Mat, Vector};
use opencv::features2d::{ORB_ScoreType, ORB};
use opencv::prelude::*;

use crate::features::descriptor_set::{BinaryDescriptor, ORB_DESCRIPTOR_BYTES};
use crate::features::{FeatureError, Keypoint};

/// Computes one 32-byte descriptor per keypoint (level-0 coordinates, with
/// `octave` and `angle` set). OpenCV keeps the keypoints' angles; its border
/// filter is disabled (edge threshold 0), so the rows stay in order; a count
/// mismatch is reported as an error.
pub fn describe(
    image: &Mat,
    keypoints: &[Keypoint],
    scale_factor: f32,
    n_levels: usize,
) -> Result<Vec<BinaryDescriptor>, FeatureError> {
    if keypoints.is_empty() {
        return Ok(Vec::new());
    }
    let mut orb = ORB::create(
        keypoints.len() as i32,
        scale_factor,
        n_levels as i32,
        0,
        0,
        2,
        ORB_ScoreType::HARRIS_SCORE,
        31,
        20,
    )?;
    let mut cv_keypoints = Vector::<KeyPoint>::with_capacity(keypoints.len());
    for kp in keypoints {
        cv_keypoints.push(KeyPoint::new_coords(
            kp.x,
            kp.y,
            kp.size,
            kp.angle,
            kp.response,
            kp.octave,
            -1,
        )?);
    }
    let mut rows = Mat::default();
    orb.compute(image, &mut cv_keypoints, &mut rows)?;
    if cv_keypoints.len() != keypoints.len() || rows.rows() as usize != keypoints.len() {
        return Err(FeatureError::OpenCv(format!(
            "ORB::compute returned {} descriptors for {} keypoints",
            rows.rows(),
            keypoints.len()
        )));
    }
    let bytes = rows.data_bytes()?;
    if bytes.len() != keypoints.len() * ORB_DESCRIPTOR_BYTES {
        return Err(FeatureError::OpenCv(format!(
            "ORB::compute returned {} bytes, expected {} per keypoint",
            bytes.len(),
            ORB_DESCRIPTOR_BYTES
        )));
    }
    Ok(bytes
        .chunks_exact(ORB_DESCRIPTOR_BYTES)
        .map(|row| {
            let mut d = [0u8; ORB_DESCRIPTOR_BYTES];
            d.copy_from_slice(row);
            d
        })
        .collect())
}
