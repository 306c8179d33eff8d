//! Pose-only refinement of a frame against its matched map points.

use crate::map::{keypoint_observation, Map};
use crate::optim::pose_only::{optimise_pose, PoseCorrespondence, PoseOnlyConfig};
use crate::optim::reprojection::Observation;

use super::frame::Frame;
use crate::camera::CameraRig;
use crate::error::{MapContext, SlamError};

/// The observation keypoint `i` of `frame` makes with the rig's stereo
/// depth limit (the one policy: [`keypoint_observation`]).
pub(crate) fn frame_observation(
    frame: &Frame,
    i: usize,
    stereo_depth_limit: f64,
) -> Option<Observation> {
    keypoint_observation(
        frame.features.keypoints.get(i)?,
        frame.stereo.get(i).copied().flatten(),
        &frame.scales,
        stereo_depth_limit,
    )
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
        let (Ok(p), Some(observation)) = (
            map.map_point(point),
            frame_observation(frame, i, rig.stereo_depth_limit()),
        ) else {
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
