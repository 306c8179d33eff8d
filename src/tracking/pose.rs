//! Pose-only refinement of a frame against its matched map points.

use crate::map::Map;
use crate::optim::pose_only::{optimise_pose, PoseCorrespondence, PoseOnlyConfig};
use crate::optim::reprojection::Observation;

use super::frame::Frame;
use crate::camera::CameraRig;
use crate::error::{MapContext, SlamError};

/// The observation keypoint `i` of `frame` makes (stereo when it has a depth).
pub(crate) fn frame_observation(frame: &Frame, i: usize) -> Option<Observation> {
    let kp = frame.features.keypoints.get(i)?;
    let octave = usize::try_from(kp.octave).ok()?;
    let information = f64::from(*frame.scales.inv_level_sigma2.get(octave)?);
    let (u, v) = (f64::from(kp.x), f64::from(kp.y));
    Some(match frame.stereo.get(i).copied().flatten() {
        Some(s) if s.depth > 0.0 => Observation::stereo(u, v, f64::from(s.right_u), information),
        _ => Observation::mono(u, v, information),
    })
}

/// Refines `frame.pose_cw` from its matches (ORB-SLAM3's `PoseOptimization`)
/// and unmatches the outliers. Returns the inliers; 0 when there were too
/// few matches to optimise.
pub(crate) fn refine_pose(
    frame: &mut Frame,
    map: &Map,
    rig: &CameraRig,
) -> Result<usize, SlamError> {
    let mut indices = Vec::new();
    let mut correspondences = Vec::new();
    for (i, point) in frame.map_points.iter().enumerate() {
        let Some(point) = point.and_then(|p| map.resolve_point(p)) else {
            continue;
        };
        let (Ok(p), Some(observation)) = (map.map_point(point), frame_observation(frame, i)) else {
            continue;
        };
        indices.push(i);
        correspondences.push(PoseCorrespondence {
            point: p.position,
            observation,
        });
    }
    let config = PoseOnlyConfig::default();
    if correspondences.len() < config.min_correspondences {
        return Ok(0);
    }
    let result = optimise_pose(&rig.camera, &frame.pose_cw, &correspondences, &config)
        .in_stage("pose-only optimisation")?;
    frame.pose_cw = result.pose;
    for (k, &i) in indices.iter().enumerate() {
        if !result.inliers[k] {
            frame.map_points[i] = None;
        }
    }
    Ok(result.inlier_count)
}
