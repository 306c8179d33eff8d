//! ORB-SLAM's outlier test for bundle-adjustment observations.

use nalgebra::Vector3;

use super::layout::Layout;
use crate::optim::reprojection::{observation_chi2, PinholeStereo, PoseMatrix};

/// Clears `active[k]` for every sorted observation whose χ² exceeds its
/// threshold (5.991 mono, 7.815 stereo) or whose point is not in front of
/// the camera; never sets a flag. Returns the inliers' χ² sum.
pub(super) fn deactivate_outliers(
    camera: &PinholeStereo,
    layout: &Layout,
    poses: &[PoseMatrix],
    points: &[Vector3<f64>],
    active: &mut [bool],
) -> f64 {
    let mut inlier_chi2 = 0.0;
    for (point, x) in points.iter().enumerate() {
        for k in layout.point_observations(point) {
            if !active[k] {
                continue;
            }
            let o = &layout.observations[k];
            let p_cam = poses[o.pose as usize].transform(x);
            let chi2 = observation_chi2(camera, &p_cam, &o.obs);
            if p_cam.z > 0.0 && chi2 <= o.obs.chi2_threshold() {
                inlier_chi2 += chi2;
            } else {
                active[k] = false;
            }
        }
    }
    inlier_chi2
}
