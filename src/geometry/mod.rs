//! Multi-view geometry that sits below the SLAM layers.
//!
//! - [`two_view`]: monocular two-view reconstruction (homography or
//!   fundamental matrix by RANSAC, motion recovery, triangulation), after
//!   ORB-SLAM3's `TwoViewReconstruction`.

pub mod two_view;

pub use two_view::{
    reconstruct_two_views, PinholeIntrinsics, TwoViewModel, TwoViewParams, TwoViewReconstruction,
    TwoViewRejection,
};
