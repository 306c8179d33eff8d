//! Tracking (ORB-SLAM3's `Tracking` for stereo, RGB-D and monocular
//! cameras, without IMU).
//!
//! - [`Frontend`]: extracts the features (a stereo pair's in parallel) and
//!   gives the keypoints their depths by sensor (stereo matching along
//!   rows, the depth image, none) into a [`Frame`];
//! - [`Tracker`]: initialisation by sensor (one frame with depths, or the
//!   monocular two-view reconstruction), the constant-velocity motion
//!   model, the reference keyframe and relocalisation as fallbacks, local
//!   map tracking, ORB-SLAM3's keyframe decision and insertion;
//! - [`SmallBlurryImage`] and [`estimate_rotation`]: the rotation between
//!   two frames from their whole images (PTAM's small blurry images), the
//!   motion model's second start in a turn it missed, and the turn of a
//!   tracking gap's rows ([`crate::system`]);
//!
//! The driver that runs tracking with local mapping over an atlas of maps
//! is [`crate::system::SlamSystem`]; tracking imports nothing from it.
//!
//! Bag-of-words place recognition is not used here: tracking the reference
//! keyframe and relocalisation match descriptors by brute force. Which
//! keyframes relocalisation tries comes through the
//! [`RelocalisationCandidates`] seam ([`Tracker::set_relocalisation_candidates`]):
//! the loop-closing keyframe database when loop closing is on
//! (`crate::loop_closing::DatabaseRelocaliser`), else the newest
//! [`MAX_SCANNED_KEYFRAMES`] keyframes.

mod after_loss;
mod between_views;
mod corroborate;
mod frame;
mod frontend;
mod gap_odometry;
mod image_rotation;
mod keyframe;
mod late;
mod local_map;
mod method;
mod mono_init;
mod motion;
mod pose;
mod relocalise;
mod search;
mod step_limit;
mod tracker;

pub use after_loss::LOST_FRAMES_KEPT_S;
pub use frame::Frame;
pub use frontend::{Extractors, FrameBuilder, Frontend, SensorFeatures, SensorImages};
pub use gap_odometry::OdometryStep;
pub use image_rotation::{estimate_rotation, ImageRotation, SmallBlurryImage};
pub use keyframe::{MIN_INITIAL_KEYPOINTS, MIN_INITIAL_STEREO_POINTS};
pub use late::LateLocalisation;
pub use mono_init::{MIN_MONO_INIT_KEYPOINTS, MIN_MONO_INIT_MATCHES};
pub use motion::MOTION_MODEL_RADIUS;
pub(crate) use pose::refine_pose;
pub(crate) use relocalise::{pnp_ransac, PNP_RANSAC_ITERATIONS};
pub use relocalise::{RelocalisationCandidates, MAX_SCANNED_KEYFRAMES, MIN_RELOCALISATION_INLIERS};
pub(crate) use search::{match_descriptors, match_projected, visible_in_frame, VisiblePoint};
pub use tracker::{
    TrackOutcome, Tracker, TrackingMethod, TrackingState, RELOCALISATION_PATIENCE_S,
    YOUNG_MAP_KEYFRAMES,
};

#[cfg(test)]
mod stage_tests;
