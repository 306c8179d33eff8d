//! Keyframes: a pose, the keypoints with their descriptor block, stereo
//! depths, and which map point each keypoint observes.

use std::sync::Arc;

use nalgebra::Vector3;

use crate::features::pyramid::ScaleTables;
use crate::features::{DescriptorSet, DistanceThresholds, Keypoint};
use crate::optim::{LieGroup, Se3};

use super::error::{MapError, Result};
use super::ids::{KeyFrameId, MapPointId};

/// A keypoint's stereo measurement: the matched column in the right image
/// and the depth it gives (`bf / (u_left − u_right)`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StereoMeasurement {
    /// Column of the match in the right image, pixels.
    pub right_u: f32,
    /// Depth along the optical axis, metres.
    pub depth: f32,
}

/// Everything a frame measured: keypoints, their descriptors (one row each)
/// and, for stereo or RGB-D, their depths.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameMeasurements {
    /// Keypoints in level-0 pixels.
    pub keypoints: Vec<Keypoint>,
    /// One descriptor row per keypoint.
    pub descriptors: DescriptorSet,
    /// One entry per keypoint; `None` where stereo matching found nothing.
    pub stereo: Vec<Option<StereoMeasurement>>,
    /// The pyramid's scale tables (octave → scale, σ²).
    pub scales: ScaleTables,
    /// The thresholds its descriptors are matched with (the extractor's:
    /// [`FeatureExtractor::distance_thresholds`](crate::features::FeatureExtractor::distance_thresholds)).
    pub distance_thresholds: DistanceThresholds,
}

impl FrameMeasurements {
    /// Checks that keypoints, descriptors and stereo entries agree in number.
    pub fn validate(&self) -> Result<()> {
        let n = self.keypoints.len();
        if self.descriptors.len() != n || self.stereo.len() != n {
            return Err(MapError::InconsistentKeyFrame {
                keypoints: n,
                descriptors: self.descriptors.len(),
                stereo: self.stereo.len(),
            });
        }
        Ok(())
    }

    /// Number of keypoints.
    pub fn len(&self) -> usize {
        self.keypoints.len()
    }

    /// True when there is no keypoint.
    pub fn is_empty(&self) -> bool {
        self.keypoints.is_empty()
    }
}

/// A keyframe in the map.
#[derive(Debug, Clone)]
pub struct KeyFrame {
    id: KeyFrameId,
    /// Index of the frame it was made from, in the input sequence.
    pub frame_index: usize,
    /// Timestamp in seconds.
    pub timestamp: f64,
    pose_cw: Se3,
    /// What the frame measured; shared, as it never changes once the
    /// keyframe is made: a copy of the keyframe (a loop check's
    /// [`Map::excerpt`](super::Map::excerpt), local mapping's triangulation
    /// snapshot) does not copy its descriptors.
    pub measurements: Arc<FrameMeasurements>,
    map_points: Vec<Option<MapPointId>>,
}

impl KeyFrame {
    /// A keyframe with no map-point associations yet.
    pub(super) fn new(
        id: KeyFrameId,
        frame_index: usize,
        timestamp: f64,
        pose_cw: Se3,
        measurements: FrameMeasurements,
    ) -> Self {
        let n = measurements.len();
        Self {
            id,
            frame_index,
            timestamp,
            pose_cw,
            measurements: Arc::new(measurements),
            map_points: vec![None; n],
        }
    }

    /// Its id.
    pub fn id(&self) -> KeyFrameId {
        self.id
    }

    /// World-to-camera pose `T_cw`.
    pub fn pose_cw(&self) -> Se3 {
        self.pose_cw
    }

    /// Camera-to-world pose `T_wc`.
    pub fn pose_wc(&self) -> Se3 {
        self.pose_cw.inverse()
    }

    /// The camera centre in world coordinates.
    pub fn camera_center(&self) -> Vector3<f64> {
        self.pose_wc().translation
    }

    /// Sets the pose (after optimisation).
    pub fn set_pose_cw(&mut self, pose_cw: Se3) {
        self.pose_cw = pose_cw;
    }

    /// The map point keypoint `index` observes, if any.
    pub fn map_point(&self, index: usize) -> Option<MapPointId> {
        self.map_points.get(index).copied().flatten()
    }

    /// The map point of every keypoint (`None` where there is none).
    pub fn map_points(&self) -> &[Option<MapPointId>] {
        &self.map_points
    }

    /// The observed map points with their keypoint index.
    pub fn observed_points(&self) -> impl Iterator<Item = (usize, MapPointId)> + '_ {
        self.map_points
            .iter()
            .enumerate()
            .filter_map(|(i, p)| p.map(|p| (i, p)))
    }

    /// Number of keypoints with a map point.
    pub fn tracked_points(&self) -> usize {
        self.map_points.iter().filter(|p| p.is_some()).count()
    }

    pub(super) fn check_index(&self, index: usize) -> Result<()> {
        if index >= self.map_points.len() {
            return Err(MapError::KeypointOutOfRange {
                keyframe: self.id,
                index,
                keypoints: self.map_points.len(),
            });
        }
        Ok(())
    }

    pub(super) fn set_map_point(&mut self, index: usize, point: Option<MapPointId>) {
        if let Some(slot) = self.map_points.get_mut(index) {
            *slot = point;
        }
    }
}
