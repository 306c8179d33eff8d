//! The frames between a monocular initialisation's two views, localised
//! once the initial map exists.
//!
//! ORB-SLAM3's `MonocularInitialization` gives no pose to the frames it
//! skips while it waits for parallax: between the reference frame and the
//! frame that initialises, every frame is lost to the trajectory (on a
//! slow handheld camera, the kitchen of 7-Scenes, 25 frames). Those frames
//! saw the same scene as the two views, so once the map exists each one is
//! tracked against it as a frame is against its reference keyframe
//! (ORB-SLAM3's `TrackReferenceKeyFrame`): descriptor matching against the
//! nearer of the two keyframes' points, the pose refined from the one
//! interpolated between theirs, kept with the inliers local-map tracking
//! needs. The map is only read: not even the points' visible and found
//! counts change (local-map tracking would raise them, and local
//! mapping's culling would then judge the initial points by frames that
//! were never tracked live; on the kitchen, SuperPoint + ANMS, the rest of
//! the run's ATE rose from 0.037 to 0.12 m that way).

use crate::camera::CameraRig;
use crate::error::{MapContext, SlamError};
use crate::map::{KeyFrameId, Map};
use crate::optim::{LieGroup, Se3};

use super::frame::Frame;
use super::late::{match_kept_frame, LateLocalisation};

/// One view of the initialisation: its keyframe and input frame index.
#[derive(Debug, Clone, Copy)]
pub(crate) struct InitialView {
    /// The keyframe made of it.
    pub keyframe: KeyFrameId,
    /// Its index in the input.
    pub index: usize,
}

/// The pose a fraction `alpha` of the way from `first` to `second`
/// (`exp(alpha · log(T_2 T_1⁻¹)) T_1`).
fn interpolated(first: &Se3, second: &Se3, alpha: f64) -> Se3 {
    let step = second.compose(&first.inverse());
    Se3::exp(&(step.log() * alpha)).compose(first)
}

/// Localises each of `frames` (between `first` and `second`, in any order)
/// against `map`; returns those with `min_inliers` local-map inliers or
/// more, in input order.
pub(crate) fn localise_between_views(
    frames: Vec<Frame>,
    first: InitialView,
    second: InitialView,
    map: &Map,
    rig: &CameraRig,
    min_inliers: usize,
) -> Result<Vec<LateLocalisation>, SlamError> {
    let first_pose = map
        .pose_cw_of(first.keyframe)
        .in_stage("frames between views")?;
    let second_pose = map
        .pose_cw_of(second.keyframe)
        .in_stage("frames between views")?;
    let span = second.index.saturating_sub(first.index).max(1) as f64;
    let mut localised = Vec::new();
    for mut frame in frames {
        if frame.index <= first.index || frame.index >= second.index {
            continue;
        }
        let alpha = (frame.index - first.index) as f64 / span;
        let prior = interpolated(&first_pose, &second_pose, alpha);
        let (nearer, nearer_pose) = if alpha < 0.5 {
            (first.keyframe, first_pose)
        } else {
            (second.keyframe, second_pose)
        };
        if !match_kept_frame(&mut frame, &prior, nearer, map, rig)? {
            tracing::debug!(frame = frame.index, "between views: too few matches");
            continue;
        }
        let inliers = frame.tracked_count();
        tracing::debug!(frame = frame.index, inliers, "between views");
        if inliers < min_inliers {
            continue;
        }
        localised.push(LateLocalisation::of(&frame, nearer, &nearer_pose, inliers));
    }
    localised.sort_by_key(|l| l.index);
    Ok(localised)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{UnitQuaternion, Vector3};

    #[test]
    fn the_interpolated_pose_runs_from_the_first_view_to_the_second() {
        let first = Se3::identity();
        let second = Se3::new(
            UnitQuaternion::from_euler_angles(0.0, 0.2, 0.0),
            Vector3::new(0.4, 0.0, -0.1),
        );
        let close = |a: &Se3, b: &Se3| a.compose(&b.inverse()).log().norm() < 1e-12;
        assert!(close(&interpolated(&first, &second, 0.0), &first));
        assert!(close(&interpolated(&first, &second, 1.0), &second));
        let half = interpolated(&first, &second, 0.5);
        assert!(close(&half.compose(&half), &second));
    }
}
