//! The frames of a loss, localised once tracking resumes.
//!
//! When tracking is lost, ORB-SLAM3 gives the frames of the loss no pose:
//! relocalisation is tried on each until it succeeds or the patience runs
//! out and a new map is started (`Tracking::Track`, `RECENTLY_LOST`). The
//! frames lost are often only hard against the old map: in a fast turn
//! with motion blur, a blurred frame matches the next blurred frame (the
//! same blur) far better than the sharp keyframes before the turn. So
//! spslam keeps the frames of the current loss (their features, at most
//! [`LOST_FRAMES_KEPT_S`] of them) and, when tracking resumes (the new
//! map's first keyframe, or a relocalised frame), walks back through them
//! from the newest: each is matched by descriptors against the keyframe
//! tracking resumed in, its pose refined from the pose of the frame after
//! it (ORB-SLAM3's `TrackReferenceKeyFrame`), then the local map is
//! searched from that pose with the wider window used just after a
//! relocalisation (`TrackLocalMap`), and the frame is kept with the
//! inliers local-map tracking needs. The local map's search matters: on
//! the synthetic block a frame matched against the keyframe alone was
//! 0.26 m off where the map put the same place, with the local map 0.04 m
//! (`tests/slam_system.rs`). The map is only read: the points' visible
//! and found counts stay as they were ([`PointCounting::ReadOnly`]), so
//! local mapping's culling judges points by the frames tracked live only
//! (for the frames between a monocular initialisation's views, see
//! [`super::between_views`], counting them made a whole run worse).

use crate::camera::CameraRig;
use crate::error::{MapContext, SlamError};
use crate::map::{KeyFrameId, Map};
use crate::optim::Se3;

use super::frame::Frame;
use super::late::{match_kept_frame, LateLocalisation};
use super::local_map::{track_local_map, PointCounting};

/// Seconds of lost frames kept for localisation once tracking resumes
/// (at least [`MIN_LOST_FRAMES_KEPT`], at most [`MAX_LOST_FRAMES_KEPT`]
/// frames): twice the relocalisation patience, so a loss that ends in a
/// new map keeps all its frames.
pub const LOST_FRAMES_KEPT_S: f64 = 1.0;
/// Lost frames kept, at least.
const MIN_LOST_FRAMES_KEPT: usize = 3;
/// Lost frames kept, at most (a SuperPoint frame's features take about
/// 1 MB).
const MAX_LOST_FRAMES_KEPT: usize = 30;

/// How many lost frames a camera at `fps` keeps.
pub(crate) fn lost_frames_kept(fps: f64) -> usize {
    ((LOST_FRAMES_KEPT_S * fps).ceil() as usize).clamp(MIN_LOST_FRAMES_KEPT, MAX_LOST_FRAMES_KEPT)
}

/// Where tracking resumed: the keyframe the lost frames are matched
/// against and the pose of the frame that resumed.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Resumption {
    /// The keyframe whose points the lost frames are matched with.
    pub keyframe: KeyFrameId,
    /// The input index of the frame that resumed tracking.
    pub index: usize,
    /// Its pose, `T_c,w`: the first lost frame's starting pose.
    pub pose_cw: Se3,
}

/// Localises the lost `frames` (any order) that came before `resumed`,
/// newest first, each from the pose of the one after it; returns those
/// with `min_inliers` local-map inliers or more, in input order.
pub(crate) fn localise_lost_frames(
    mut frames: Vec<Frame>,
    resumed: Resumption,
    map: &Map,
    rig: &CameraRig,
    min_inliers: usize,
) -> Result<Vec<LateLocalisation>, SlamError> {
    let keyframe_pose = map
        .pose_cw_of(resumed.keyframe)
        .in_stage("frames lost before tracking resumed")?;
    frames.retain(|f| f.index < resumed.index && !f.features.keypoints.is_empty());
    frames.sort_by_key(|f| std::cmp::Reverse(f.index));
    let mut prior = resumed.pose_cw;
    let mut localised = Vec::new();
    for mut frame in frames {
        if !match_kept_frame(&mut frame, &prior, resumed.keyframe, map, rig)? {
            tracing::debug!(frame = frame.index, "after a loss: too few matches");
            continue;
        }
        // The local map around the keyframe, searched from that pose (as
        // just after a relocalisation), refines it with more points.
        let from_keyframe = frame.tracked_count();
        let inliers = track_local_map(&mut frame, map, rig, true, PointCounting::ReadOnly)?.inliers;
        tracing::debug!(frame = frame.index, from_keyframe, inliers, "after a loss");
        if inliers < min_inliers {
            continue;
        }
        prior = frame.pose_cw;
        localised.push(LateLocalisation::of(
            &frame,
            resumed.keyframe,
            &keyframe_pose,
            inliers,
        ));
    }
    localised.sort_by_key(|l| l.index);
    Ok(localised)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_of_frames_is_kept_within_bounds() {
        assert_eq!(lost_frames_kept(10.0), 10);
        assert_eq!(lost_frames_kept(1.0), MIN_LOST_FRAMES_KEPT);
        assert_eq!(lost_frames_kept(200.0), MAX_LOST_FRAMES_KEPT);
    }
}
