//! A frame given a pose after the fact: tracking could not place it when
//! it arrived, and a later event (a monocular map made, tracking resumed
//! after a loss) made it possible.

use crate::camera::CameraRig;
use crate::error::SlamError;
use crate::map::{KeyFrameId, Map};
use crate::optim::{LieGroup, Se3};

use super::frame::Frame;
use super::motion::track_reference_keyframe;

/// A frame localised after the fact, relative to a keyframe.
#[derive(Debug, Clone, PartialEq)]
pub struct LateLocalisation {
    /// Its index in the input.
    pub index: usize,
    /// The keyframe its pose is relative to.
    pub keyframe: KeyFrameId,
    /// `T_c,kf`.
    pub relative_pose: Se3,
    /// Inliers of its pose.
    pub inliers: usize,
}

impl LateLocalisation {
    /// `frame`'s pose relative to `keyframe`, whose pose is
    /// `keyframe_pose` (`T_kf,w`), with `inliers`.
    pub(crate) fn of(
        frame: &Frame,
        keyframe: KeyFrameId,
        keyframe_pose: &Se3,
        inliers: usize,
    ) -> Self {
        Self {
            index: frame.index,
            keyframe,
            relative_pose: frame.pose_cw.compose(&keyframe_pose.inverse()),
            inliers,
        }
    }
}

/// Matches a kept frame afresh against `keyframe`'s points and refines its
/// pose from `prior` (ORB-SLAM3's `TrackReferenceKeyFrame`); whatever it
/// was matched with before is dropped. Whether a pose was found.
pub(crate) fn match_kept_frame(
    frame: &mut Frame,
    prior: &Se3,
    keyframe: KeyFrameId,
    map: &Map,
    rig: &CameraRig,
) -> Result<bool, SlamError> {
    frame.map_points.iter_mut().for_each(|slot| *slot = None);
    frame.reference_keyframe = Some(keyframe);
    track_reference_keyframe(frame, prior, keyframe, map, rig)
}
