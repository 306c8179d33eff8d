//! Frame-to-frame tracking: the constant-velocity motion model and, as its
//! fallback, descriptor matching against the reference keyframe.

use crate::map::{KeyFrameId, Map, MapPointId};
use crate::optim::{LieGroup, Se3};

use super::error::SlamError;
use super::frame::Frame;
use super::pose::refine_pose;
use super::rig::StereoRig;
use super::search::{match_descriptors, match_projected, VisiblePoint};

/// ORB-SLAM3's window for stereo (`th = 7`), in level-0 pixels per scale.
pub const MOTION_MODEL_RADIUS: f32 = 7.0;

/// Projects the last frame's points with the current pose estimate,
/// predicting each at the octave it was seen at.
fn last_frame_points(frame: &Frame, last: &Frame, map: &Map, rig: &StereoRig) -> Vec<VisiblePoint> {
    let mut out = Vec::new();
    for (i, point) in last.map_points.iter().enumerate() {
        let Some(id) = point.and_then(|p| map.resolve_point(p)) else {
            continue;
        };
        let Ok(p) = map.map_point(id) else { continue };
        let pc = frame.pose_cw.transform_point(&p.position);
        if pc.z <= 0.0 {
            continue;
        }
        let uvr = rig.camera.project_stereo(&pc);
        if !rig.contains(uvr.x, uvr.y) {
            continue;
        }
        out.push(VisiblePoint {
            id,
            u: uvr.x as f32,
            v: uvr.y as f32,
            u_right: uvr.z as f32,
            octave: last.features.keypoints[i].octave,
            frontal: true,
        });
    }
    out
}

/// ORB-SLAM3's `TrackWithMotionModel`: predicts the pose from the last
/// frame's and the velocity, searches the last frame's points around their
/// projections (window 7·scale, then twice that), then refines the pose.
/// True when at least 10 inliers remain.
pub fn track_with_motion_model(
    frame: &mut Frame,
    last: &Frame,
    velocity: &Se3,
    map: &Map,
    rig: &StereoRig,
) -> Result<bool, SlamError> {
    frame.pose_cw = velocity.compose(&last.pose_cw);
    frame.map_points.iter_mut().for_each(|p| *p = None);
    let points = last_frame_points(frame, last, map, rig);
    let mut matches = match_projected(frame, map, &points, MOTION_MODEL_RADIUS, (1, 1), None)?;
    if matches < 20 {
        frame.map_points.iter_mut().for_each(|p| *p = None);
        matches = match_projected(frame, map, &points, 2.0 * MOTION_MODEL_RADIUS, (1, 1), None)?;
    }
    if matches < 20 {
        return Ok(false);
    }
    Ok(refine_pose(frame, map, rig)? >= 10)
}

/// ORB-SLAM3's `TrackReferenceKeyFrame`, with descriptor matching (ratio
/// 0.7, mutual) instead of bag-of-words: starting from the last pose, needs
/// 15 matches and 10 inliers after refinement.
pub fn track_reference_keyframe(
    frame: &mut Frame,
    last_pose: &Se3,
    reference: KeyFrameId,
    map: &Map,
    rig: &StereoRig,
) -> Result<bool, SlamError> {
    let Ok(kf) = map.keyframe(reference) else {
        return Ok(false);
    };
    let points: Vec<MapPointId> = kf.observed_points().map(|(_, p)| p).collect();
    let matches = match_descriptors(frame, map, &points, 0.7)?;
    if matches.len() < 15 {
        return Ok(false);
    }
    frame.map_points.iter_mut().for_each(|p| *p = None);
    for (i, p) in matches {
        frame.map_points[i] = Some(p);
    }
    frame.pose_cw = *last_pose;
    Ok(refine_pose(frame, map, rig)? >= 10)
}
