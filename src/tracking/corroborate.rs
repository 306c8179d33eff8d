//! A lost frame's pose, corroborated by a second start.
//!
//! When frame-to-frame tracking fails, the tracker tries several starts
//! (the reference keyframe, the last frame, the images' rotation, the
//! motion model's rejected pose, mutual nearest neighbours), each followed
//! by the local map's search. A start away from the motion model's
//! prediction must reach the 50 inliers of a relocalisation for tracking
//! to go on (ORB-SLAM3's `TrackLocalMap`), because a wrong pose that goes
//! on inserts keyframes. A frame's record asks less of a pose that changes
//! nothing in the map: the inliers local-map tracking needs (30), as for
//! the frames localised after a loss ([`super::after_loss`]), and a second
//! start that lands on the same pose. Two starts are independent ways in
//! (different matches, different first poses); a pose both reach is the
//! one the local map supports, where a wrong pose, found by one start
//! among repeated façades, is not found again by another. "The same pose"
//! is judged in the image: the best pose's matched points, projected with
//! the other start's pose, fall within ORB-SLAM3's inlier bound of where
//! the best pose puts them (median over the points, 2.45 px: the χ² bound
//! at 95 % for two degrees of freedom, √5.991).
//!
//! On the low-texture lap (stereo, SuperPoint + ANMS) the frame lost at
//! the third corner had 48 local-map inliers from the images' rotation and
//! 24 to 29 from three other starts, all within 5 cm and 0.4° of it; a
//! camera kidnapped three quarters of the way round the block
//! (`tests/slam_system.rs`) found 33 inliers from the images' rotation at
//! a wrong place, and the only other start with a pose was 0.4 m and 1.7°
//! away from it.

use crate::camera::CameraRig;
use crate::map::Map;
use crate::optim::{LieGroup, Se3};

use super::frame::Frame;
use super::method::TrackingMethod;
use super::motion::MIN_POSE_INLIERS;

/// Median image distance, pixels, within which two poses agree (√5.991).
pub(crate) const SAME_POSE_PX: f64 = 2.45;

/// A start's pose after the local map's search.
#[derive(Debug, Clone, Copy)]
pub(crate) struct StartPose {
    /// How it started.
    pub method: TrackingMethod,
    /// `T_c,w` after the local map.
    pub pose_cw: Se3,
    /// Its local-map inliers.
    pub inliers: usize,
}

/// Whether the lost `frame`'s pose (found by `method`, with `inliers`)
/// will do for its record: `min_inliers` (local-map tracking's), and
/// another start with a pose ([`MIN_POSE_INLIERS`]) that agrees with it
/// ([`median_image_distance`] within [`SAME_POSE_PX`]).
pub(crate) fn corroborated(
    frame: &Frame,
    (method, inliers): (TrackingMethod, usize),
    min_inliers: usize,
    starts: &[StartPose],
    map: &Map,
    rig: &CameraRig,
) -> bool {
    if inliers < min_inliers
        || matches!(
            method,
            TrackingMethod::None | TrackingMethod::Relocalisation
        )
    {
        return false;
    }
    starts
        .iter()
        .filter(|s| s.method != method && s.inliers >= MIN_POSE_INLIERS)
        .filter_map(|s| median_image_distance(frame, &s.pose_cw, map, rig))
        .inspect(|d| tracing::debug!(frame = frame.index, distance_px = d, "corroboration"))
        .any(|d| d <= SAME_POSE_PX)
}

/// The median distance, pixels, between where `frame`'s pose and `other`
/// project the frame's matched points; `None` without a point both see.
pub(crate) fn median_image_distance(
    frame: &Frame,
    other: &Se3,
    map: &Map,
    rig: &CameraRig,
) -> Option<f64> {
    let mut distances: Vec<f64> = frame
        .map_points
        .iter()
        .flatten()
        .filter_map(|id| map.map_point(*id).ok())
        .filter_map(|p| {
            let a = rig.project_in_image(&frame.pose_cw.transform_point(&p.position))?;
            let b = rig.project_in_image(&other.transform_point(&p.position))?;
            Some(((a.x - b.x).powi(2) + (a.y - b.y).powi(2)).sqrt())
        })
        .collect();
    crate::stats::upper_median(&mut distances)
}
