//! Frame-to-frame tracking: the constant-velocity motion model and, as its
//! fallback, descriptor matching against the reference keyframe.

use crate::map::{KeyFrameId, Map, MapPointId};
use crate::optim::{LieGroup, Se3};

use super::frame::Frame;
use super::image_rotation::estimate_rotation;
use super::pose::refine_pose;
use super::relocalise::{pnp_ransac, PNP_RANSAC_ITERATIONS};
use super::search::{
    keyframe_points_in_view, match_descriptors_in_view, match_projected, VisiblePoint,
};
use crate::camera::{CameraRig, Sensor};
use crate::error::SlamError;
use crate::features::Keypoint;

/// ORB-SLAM3's window for stereo (`th = 7`), in level-0 pixels per scale.
pub const MOTION_MODEL_RADIUS: f32 = 7.0;
/// ORB-SLAM3's window for monocular and RGB-D (`th = 15`).
pub const MOTION_MODEL_RADIUS_SINGLE: f32 = 15.0;

/// The motion model's window for the rig's sensor (ORB-SLAM3's
/// `TrackWithMotionModel`: 7 for stereo, 15 otherwise).
fn motion_model_radius(rig: &CameraRig) -> f32 {
    if rig.sensor == Sensor::Stereo {
        MOTION_MODEL_RADIUS
    } else {
        MOTION_MODEL_RADIUS_SINGLE
    }
}

/// A keypoint's octave in another frame, as the predicted octave in
/// `frame`: the same, or `frame`'s top level when it has fewer (a last
/// frame extracted on a deeper pyramid by the second look), so that the
/// search's octave window still reaches `frame`'s levels.
pub(crate) fn octave_within(octave: i32, frame: &Frame) -> i32 {
    let top = frame.scales.n_levels().saturating_sub(1);
    octave.min(i32::try_from(top).unwrap_or(i32::MAX))
}

/// Projects the last frame's points with the current pose estimate,
/// predicting each at the octave it was seen at (see [`octave_within`]).
fn last_frame_points(frame: &Frame, last: &Frame, map: &Map, rig: &CameraRig) -> Vec<VisiblePoint> {
    let mut out = Vec::new();
    for (i, point) in last.map_points.iter().enumerate() {
        let Some(id) = point.and_then(|p| map.resolve_point(p)) else {
            continue;
        };
        let Ok(p) = map.map_point(id) else { continue };
        let Some(uvr) = rig.project_in_image(&frame.pose_cw.transform_point(&p.position)) else {
            continue;
        };
        out.push(VisiblePoint {
            id,
            u: uvr.x as f32,
            v: uvr.y as f32,
            u_right: uvr.z as f32,
            octave: octave_within(last.features.keypoints[i].octave, frame),
            frontal: true,
        });
    }
    out
}

/// How well the motion model's prediction held.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct MotionModelFit {
    /// Matches found around the predicted projections.
    pub matches: usize,
    /// Of those, inliers after pose refinement.
    pub inliers: usize,
}

impl MotionModelFit {
    /// Fewer than half the matches survived: the prediction was probably
    /// off (a turn starting or ending) and the refined pose may rest on a
    /// few far points that cannot fix the translation. Tracking then tries
    /// the reference keyframe as well and keeps the better pose.
    pub fn is_doubtful(&self) -> bool {
        2 * self.inliers < self.matches
    }

    /// ORB-SLAM3 needs 10 inliers; a prediction far off (a turn starting)
    /// also finds many wrong matches in its windows, so spslam requires
    /// the inliers to be at least a quarter of them too.
    pub fn is_accepted(&self) -> bool {
        self.inliers >= MIN_POSE_INLIERS && 4 * self.inliers >= self.matches
    }
}

/// Inliers a refined pose needs (ORB-SLAM3's `TrackWithMotionModel` and
/// `TrackReferenceKeyFrame`: 10).
pub(crate) const MIN_POSE_INLIERS: usize = 10;

/// ORB-SLAM3's `TrackWithMotionModel`: predicts the pose from the last
/// frame's and the velocity, searches the last frame's points around their
/// projections (window 7·scale, then twice that), then refines the pose.
/// The fit whenever 20 matches were found; the caller accepts it by
/// [`MotionModelFit::is_accepted`].
pub(crate) fn track_with_motion_model(
    frame: &mut Frame,
    last: &Frame,
    velocity: &Se3,
    map: &Map,
    rig: &CameraRig,
) -> Result<Option<MotionModelFit>, SlamError> {
    frame.pose_cw = velocity.compose(&last.pose_cw);
    frame.map_points.iter_mut().for_each(|p| *p = None);
    let points = last_frame_points(frame, last, map, rig);
    let radius = motion_model_radius(rig);
    let mut matches = match_projected(frame, map, &points, radius, (1, 1), None)?;
    if matches < 20 {
        frame.map_points.iter_mut().for_each(|p| *p = None);
        matches = match_projected(frame, map, &points, 2.0 * radius, (1, 1), None)?;
    }
    if matches < 20 {
        tracing::debug!(
            frame = frame.index,
            projected = points.len(),
            matches,
            "motion model: too few matches"
        );
        return Ok(None);
    }
    let inliers = refine_pose(frame, map, rig)?;
    tracing::debug!(frame = frame.index, matches, inliers, "motion model");
    Ok(Some(MotionModelFit { matches, inliers }))
}

/// Rotations closer than this to the motion model's are not tried again.
const SAME_ROTATION_DEG: f64 = 0.25;

/// The motion model's velocity with its rotation replaced by the one
/// measured between the last frame's thumbnail and this frame's
/// ([`estimate_rotation`], PTAM's small blurry images): the camera centre
/// still moves as the velocity says (not at all without one). `None`
/// without both thumbnails, when the images give no rotation, or when it
/// is the velocity's own (within 0.25°), which the motion model has tried.
pub(crate) fn image_rotation_velocity(
    frame: &Frame,
    last: &Frame,
    velocity: Option<&Se3>,
) -> Option<Se3> {
    let (Some(current), Some(previous)) = (frame.thumbnail.as_deref(), last.thumbnail.as_deref())
    else {
        return None;
    };
    let velocity = velocity.copied().unwrap_or_else(Se3::identity);
    let found = estimate_rotation(previous, current, &velocity.rotation)?;
    let change = (velocity.rotation.inverse() * found.rotation)
        .angle()
        .to_degrees();
    tracing::debug!(
        frame = frame.index,
        change_deg = change,
        rms = found.rms,
        overlap = found.overlap,
        "rotation from the images"
    );
    if change < SAME_ROTATION_DEG {
        return None;
    }
    // The camera centre in the last frame's coordinates: c = −Rᵀ·t.
    let centre = -(velocity.rotation.inverse() * velocity.translation);
    Some(Se3::new(found.rotation, -(found.rotation * centre)))
}

/// ORB-SLAM3's `TrackReferenceKeyFrame`, with descriptor matching (ratio
/// 0.7, mutual) instead of bag-of-words: starting from the last pose, needs
/// 15 matches and 10 inliers after refinement. When fewer than half the
/// matches survive (a sudden turn puts the last pose far off), a PnP RANSAC
/// pose is refined as well and the one with more inliers is kept.
///
/// The ratio test does not pit two of the keyframe's points less than the
/// descriptor cell apart in its image against each other
/// ([`match_descriptors_in_view`]), as the search by projection does not:
/// SuperPoint's neighbours within a cell share most of their descriptor,
/// and the plain test dropped the frame keypoints of many a point with
/// such a neighbour. That is what lost the demo lap's third corner when
/// local mapping lags (`spslam run --inline-mapping --mapping-lag 5`,
/// RGB-D, SuperPoint + ANMS): at frame 137 the motion model failed in the
/// turn, the reference keyframe gave 16 matches with the plain test, and
/// frames 137–141 were lost (227/232, a second map merged back, ATE
/// 0.49 m); with the rivals beyond the cell every frame is tracked in one
/// map (0.13 m; EVALUATION.md, "Local mapping that lags").
pub(crate) fn track_reference_keyframe(
    frame: &mut Frame,
    last_pose: &Se3,
    reference: KeyFrameId,
    map: &Map,
    rig: &CameraRig,
) -> Result<bool, SlamError> {
    let Ok(kf) = map.keyframe(reference) else {
        return Ok(false);
    };
    let points = keyframe_points_in_view(kf);
    track_by_descriptors(frame, last_pose, &points, map, rig, "reference keyframe")
}

/// The same descriptor matching against the last frame's tracked points
/// (spslam's addition, not in ORB-SLAM3). Where the motion model's
/// prediction fails (a turn starts or ends) and the reference keyframe
/// is several frames behind (local mapping lags, so keyframes were
/// refused), the last frame is the view closest to the current one.
pub(crate) fn track_last_frame(
    frame: &mut Frame,
    last: &Frame,
    map: &Map,
    rig: &CameraRig,
) -> Result<bool, SlamError> {
    let points = tracked_points(last, map);
    track_by_descriptors(frame, &last.pose_cw, &points, map, rig, "last frame")
}

/// The frame's tracked points (live in `map`), each with its keypoint.
fn tracked_points<'f>(frame: &'f Frame, map: &Map) -> Vec<(MapPointId, &'f Keypoint)> {
    frame
        .map_points
        .iter()
        .zip(&frame.features.keypoints)
        .filter_map(|(p, k)| Some((map.resolve_point((*p)?)?, k)))
        .collect()
}

/// The last start before a frame is lost: the last frame's tracked points
/// matched to the frame by mutual nearest neighbour **without** the ratio
/// test, a PnP RANSAC pose from those matches, refined. ORB-SLAM3's ratio
/// tests (0.7 in `TrackReferenceKeyFrame`, 0.75 in `Relocalization`) were
/// set for ORB's binary descriptors; the shipped SuperPoint weights
/// (trained on radar images) rarely pass them on bare façades although
/// their mutual nearest neighbour is mostly right. On the low-texture lap
/// (`spslam synth --condition low-texture`, frames 20 → 21, where an
/// 11.5° turn starts at once and moves the image 78 px), 27 of the two
/// frames' 1000 keypoints pass the 0.7 test (22 right), while 239 are
/// mutual nearest neighbours and 150 of those are right (63 %), which
/// RANSAC separates easily. The caller keeps the pose only when local-map
/// tracking then finds its 30 inliers.
pub(crate) fn track_last_frame_unratioed(
    frame: &mut Frame,
    last: &Frame,
    map: &Map,
    rig: &CameraRig,
) -> Result<bool, SlamError> {
    let points = tracked_points(last, map);
    let matches = match_descriptors_in_view(frame, map, &points, UNRATIOED)?;
    if matches.len() < MIN_UNRATIOED_MATCHES {
        tracing::debug!(
            frame = frame.index,
            matches = matches.len(),
            "mutual nearest neighbours: too few matches"
        );
        return Ok(false);
    }
    let Some(pose) = pnp_ransac(frame, map, &matches, rig, UNRATIOED_RANSAC_ITERATIONS)? else {
        tracing::debug!(
            frame = frame.index,
            matches = matches.len(),
            "mutual nearest neighbours: no PnP RANSAC pose"
        );
        return Ok(false);
    };
    pose.start(frame, &matches);
    let inliers = refine_pose(frame, map, rig)?;
    tracing::debug!(
        frame = frame.index,
        matches = matches.len(),
        ransac_inliers = pose.inliers(),
        inliers,
        "mutual nearest neighbours"
    );
    Ok(inliers >= MIN_POSE_INLIERS)
}

/// A ratio that only exact ties fail (the best is never above the second
/// best): mutual nearest neighbours under the distance bound.
const UNRATIOED: f32 = 1.0;
/// Matches the unratioed start needs before RANSAC is tried.
const MIN_UNRATIOED_MATCHES: usize = 20;
/// RANSAC iterations for the unratioed matches, of which a third may be
/// right: EPnP draws 5, and 300 iterations (ORB-SLAM3's) find a clean
/// sample of a 30 % inlier set only half the time (1 − (1 − 0.3⁵)³⁰⁰);
/// 2000 find one 99 % of the time. OpenCV stops sooner when the inliers
/// it finds allow.
const UNRATIOED_RANSAC_ITERATIONS: i32 = 2000;

/// Matches `points` to the frame by descriptor and refines the pose from
/// `last_pose` (or a PnP RANSAC pose); see [`track_reference_keyframe`].
fn track_by_descriptors(
    frame: &mut Frame,
    last_pose: &Se3,
    points: &[(MapPointId, &Keypoint)],
    map: &Map,
    rig: &CameraRig,
    against: &'static str,
) -> Result<bool, SlamError> {
    let matches = match_descriptors_in_view(frame, map, points, 0.7)?;
    if matches.len() < 15 {
        tracing::debug!(
            frame = frame.index,
            against,
            points = points.len(),
            matches = matches.len(),
            "descriptor tracking: too few matches"
        );
        return Ok(false);
    }
    let assign = |frame: &mut Frame| {
        frame.map_points.iter_mut().for_each(|p| *p = None);
        for &(i, p) in &matches {
            frame.map_points[i] = Some(p);
        }
    };
    assign(frame);
    frame.pose_cw = *last_pose;
    let from_last = refine_pose(frame, map, rig)?;
    tracing::debug!(
        frame = frame.index,
        against,
        matches = matches.len(),
        from_last,
        "descriptor tracking"
    );
    if 2 * from_last < matches.len() {
        if let Some(pose) = pnp_ransac(frame, map, &matches, rig, PNP_RANSAC_ITERATIONS)? {
            let (kept_pose, kept_points) = (frame.pose_cw, frame.map_points.clone());
            pose.start(frame, &matches);
            let from_pnp = refine_pose(frame, map, rig)?;
            tracing::debug!(
                frame = frame.index,
                against,
                from_last,
                from_pnp,
                "descriptor tracking: PnP RANSAC start"
            );
            if from_pnp <= from_last {
                frame.pose_cw = kept_pose;
                frame.map_points = kept_points;
            } else {
                return Ok(from_pnp >= MIN_POSE_INLIERS);
            }
        }
    }
    Ok(from_last >= MIN_POSE_INLIERS)
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;

    use super::octave_within;
    use crate::features::pyramid::ScaleTables;
    use crate::test_world::{pose_at, PointWorld};

    #[test]
    fn an_octave_beyond_the_frames_pyramid_is_its_top_level() {
        let world = PointWorld::new(3, 10, (3.0, 2.0, 8.0, 12.0));
        let (mut frame, _) = world.frame(0, &pose_at(Vector3::zeros(), 0.0), true);
        // Eight levels: every octave of a four-level frame is kept.
        assert_eq!(
            (0..4).map(|o| octave_within(o, &frame)).collect::<Vec<_>>(),
            [0, 1, 2, 3]
        );
        // One level (the default run's pyramid): a four-level last frame's
        // octaves 1-3 are searched on level 0.
        frame.scales = ScaleTables::new(1000, 1.2, 1);
        assert_eq!(
            (0..4).map(|o| octave_within(o, &frame)).collect::<Vec<_>>(),
            [0, 0, 0, 0]
        );
        assert_eq!(octave_within(-1, &frame), -1, "an unset octave stays unset");
    }
}
