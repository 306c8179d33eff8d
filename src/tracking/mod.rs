//! Stereo tracking (ORB-SLAM3's `Tracking` for rectified stereo) and the
//! [`StereoSlam`] driver that runs it with local mapping.
//!
//! - [`StereoFrontend`]: extracts left and right features in parallel and
//!   matches them along rows into a [`Frame`];
//! - [`Tracker`]: stereo initialisation, the constant-velocity motion
//!   model, the reference keyframe and relocalisation as fallbacks, local
//!   map tracking, ORB-SLAM3's stereo keyframe decision and insertion;
//! - [`StereoSlam`]: front end, tracker and [`crate::mapping::LocalMapper`]
//!   over one [`crate::map::SharedMap`], with per-frame poses kept relative
//!   to their reference keyframe so the trajectory reflects later BA and culling.
//!
//! Bag-of-words place recognition is not used: tracking the reference
//! keyframe and relocalisation match descriptors by brute force.

mod error;
mod frame;
mod frontend;
mod keyframe;
mod local_map;
mod motion;
mod pose;
mod relocalise;
mod rig;
mod search;
mod system;
mod tracker;

pub(crate) use error::MapContext;
pub use error::SlamError;
pub use frame::Frame;
pub use frontend::{FrontendTimings, StereoFeatures, StereoFrontend};
pub use keyframe::{
    initialise_map, insert_keyframe, needs_keyframe, KeyFrameContext, MIN_INITIAL_KEYPOINTS,
    MIN_INITIAL_STEREO_POINTS,
};
pub use local_map::{track_local_map, LocalMapOutcome};
pub use motion::{track_reference_keyframe, track_with_motion_model, MOTION_MODEL_RADIUS};
pub use relocalise::{relocalise, MIN_RELOCALISATION_INLIERS};
pub use rig::StereoRig;
pub use system::{FrameRecord, FrameTimings, SlamSummary, StereoSlam};
pub use tracker::{TrackOutcome, Tracker, TrackingMethod, TrackingState};
