//! Errors from map operations given ids or indices that do not fit.

use super::ids::{KeyFrameId, MapPointId};

/// A map operation referred to something that is not there.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MapError {
    /// No live keyframe has this id.
    #[error("{0} is not in the map (never added, or culled)")]
    UnknownKeyFrame(KeyFrameId),
    /// No live map point has this id.
    #[error("{0} is not in the map (never added, culled or fused)")]
    UnknownMapPoint(MapPointId),
    /// A keypoint index past the keyframe's keypoints.
    #[error("{keyframe} has {keypoints} keypoints; index {index} is out of range")]
    KeypointOutOfRange {
        /// The keyframe.
        keyframe: KeyFrameId,
        /// The index given.
        index: usize,
        /// How many keypoints it has.
        keypoints: usize,
    },
    /// The keyframe's keypoint already observes another point.
    #[error("{keyframe} keypoint {index} already observes {existing}")]
    KeypointTaken {
        /// The keyframe.
        keyframe: KeyFrameId,
        /// The keypoint index.
        index: usize,
        /// The point it observes.
        existing: MapPointId,
    },
    /// Keyframe data whose parts disagree in length.
    #[error("keyframe data is inconsistent: {keypoints} keypoints, {descriptors} descriptors, {stereo} stereo entries")]
    InconsistentKeyFrame {
        /// Keypoints given.
        keypoints: usize,
        /// Descriptor rows given.
        descriptors: usize,
        /// Stereo entries given.
        stereo: usize,
    },
    /// Absorbing a map whose ids overlap this map's.
    #[error("cannot absorb a map whose ids overlap this one's: {what} {id} is in both")]
    IdCollision {
        /// "keyframe" or "map point".
        what: &'static str,
        /// The id in both.
        id: u64,
    },
    /// A map with depth measurements cannot be scaled.
    #[error("cannot scale a map by {scale}: {keyframe} holds depth measurements, whose scale is the sensor's")]
    ScaledDepths {
        /// A keyframe with depths.
        keyframe: KeyFrameId,
        /// The scale asked for.
        scale: f64,
    },
    /// Joining spanning trees at a keyframe that is not live.
    #[error("cannot join the maps' spanning trees at {0}: it is not live")]
    JoinAtUnknownKeyFrame(KeyFrameId),
}

/// Result alias for map operations.
pub type Result<T> = std::result::Result<T, MapError>;
