//! What a frame's tracking came to: the tracker's state and how a pose was
//! found.

/// Where tracking stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum TrackingState {
    /// No map yet: waiting for a frame with enough stereo points.
    NotInitialised,
    /// The last frame was tracked.
    Ok,
    /// Tracking failed; relocalisation is tried on each frame.
    Lost,
}

/// How a frame's pose was found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum TrackingMethod {
    /// It initialised the map.
    Initialisation,
    /// Constant-velocity motion model.
    MotionModel,
    /// The motion model with the rotation measured from the whole images
    /// (a turn the constant velocity missed).
    ImageRotation,
    /// Descriptor matching against the reference keyframe.
    ReferenceKeyFrame,
    /// Descriptor matching against the last frame (where the motion model
    /// and the reference keyframe left too few local-map inliers).
    LastFrame,
    /// Mutual nearest neighbours against the last frame, without the ratio
    /// test, and PnP RANSAC: the last start before a frame is lost.
    MutualNearestNeighbours,
    /// Relocalisation against the keyframes.
    Relocalisation,
    /// A frame between a monocular initialisation's two views, localised
    /// in the map they made (after the fact).
    BetweenInitialViews,
    /// A frame lost, localised after the fact once tracking resumed (in a
    /// new map, or in the old one after a relocalisation; see
    /// [`super::after_loss`]).
    AfterLoss,
    /// A frame lost by tracking's rule whose pose a second start
    /// corroborated (see [`super::corroborate`]): its record has the pose
    /// and says `Ok`; tracking stays lost and the map is not changed.
    Corroborated,
    /// A lost frame joined to a frame with a pose by a chain of steps
    /// measured by stereo odometry between consecutive frames (see
    /// [`super::gap_odometry`]; the run's records chain them, forwards from
    /// the last tracked frame or backwards from the next one with a pose):
    /// its record has that pose and says `Ok`; tracking stays lost and the
    /// map is not changed.
    Odometry,
    /// No pose.
    None,
}
