//! A frame given a pose after the fact: tracking could not place it when
//! it arrived, and a later event (a monocular map made, tracking resumed
//! after a loss) made it possible.

use crate::map::KeyFrameId;
use crate::optim::Se3;

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
