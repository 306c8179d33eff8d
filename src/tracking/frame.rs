//! A tracked frame: features from both images, stereo depths, the grid, the
//! map points its keypoints are matched to, and its pose.

use crate::features::pyramid::{level_to_base_offset, ScaleTables};
use crate::features::{DistanceThresholds, FrameFeatures};
use crate::map::{FrameMeasurements, KeyFrame, KeyFrameId, MapPointId, StereoMeasurement};
use crate::matching::KeypointGrid;
use crate::optim::{LieGroup, Se3};

use std::sync::Arc;

use super::image_rotation::SmallBlurryImage;
use crate::camera::CameraRig;

/// One stereo frame being tracked.
#[derive(Debug, Clone)]
pub struct Frame {
    /// Index in the input sequence.
    pub index: usize,
    /// Timestamp, seconds.
    pub timestamp: f64,
    /// Left keypoints and descriptors.
    pub features: FrameFeatures,
    /// Per left keypoint: its stereo match, if any (after the `max_depth` filter).
    pub stereo: Vec<Option<StereoMeasurement>>,
    /// The extractor's scale tables.
    pub scales: ScaleTables,
    /// Left keypoints bucketed for area queries.
    pub grid: KeypointGrid,
    /// Per keypoint: the map point it is matched to.
    pub map_points: Vec<Option<MapPointId>>,
    /// The pose `T_cw` (a prediction until tracking succeeds).
    pub pose_cw: Se3,
    /// The keyframe this frame's pose is stored relative to.
    pub reference_keyframe: Option<KeyFrameId>,
    /// The cell of the lattice the descriptors were sampled from, in level
    /// pixels (SuperPoint: 8), or `None` when each keypoint has its own
    /// (ORB): keypoints closer than a cell share much of their descriptor
    /// (see [`FeatureExtractor::descriptor_cell`](crate::features::FeatureExtractor::descriptor_cell)).
    pub descriptor_cell: Option<f32>,
    /// The thresholds its descriptors are matched with (the extractor's;
    /// the kind's default until the front end sets them).
    pub distance_thresholds: DistanceThresholds,
    /// The image shrunk and blurred, for the rotation between frames when
    /// a turn outruns the motion model (`None` for a frame built without
    /// its image, or a flat one).
    pub thumbnail: Option<Arc<SmallBlurryImage>>,
}

impl Frame {
    /// A frame from its features and stereo matches; no map point yet,
    /// identity pose. Keypoints from pyramid levels are moved from the
    /// extractors' `x·s` (ORB-SLAM3's convention, kept at the C ABI) to
    /// the pixel-centre-exact `(x + ½)·s − ½` of the bilinear pyramid, and
    /// their right columns with them (the disparity is unchanged).
    pub fn new(
        index: usize,
        timestamp: f64,
        mut features: FrameFeatures,
        mut stereo: Vec<Option<StereoMeasurement>>,
        scales: ScaleTables,
        rig: &CameraRig,
    ) -> Self {
        for (kp, st) in features.keypoints.iter_mut().zip(stereo.iter_mut()) {
            let Some(scale) = scales.scale_at(kp.octave) else {
                continue;
            };
            let offset = level_to_base_offset(scale);
            kp.x += offset;
            kp.y += offset;
            if let Some(st) = st {
                st.right_u += offset;
            }
        }
        let grid = KeypointGrid::new(&features.keypoints, rig.width, rig.height);
        let n = features.len();
        let distance_thresholds = DistanceThresholds::for_kind(features.descriptors.kind());
        Self {
            index,
            timestamp,
            features,
            stereo,
            scales,
            grid,
            map_points: vec![None; n],
            pose_cw: Se3::identity(),
            reference_keyframe: None,
            descriptor_cell: None,
            distance_thresholds,
            thumbnail: None,
        }
    }

    /// A keyframe seen again as a frame (loop verification): its keypoints
    /// (already pixel-centre-exact), descriptors, stereo matches, map points
    /// and pose.
    pub fn from_keyframe(kf: &KeyFrame, rig: &CameraRig) -> Self {
        let m = &kf.measurements;
        Self {
            index: kf.frame_index,
            timestamp: kf.timestamp,
            features: FrameFeatures {
                keypoints: m.keypoints.clone(),
                descriptors: m.descriptors.clone(),
                timings: Default::default(),
            },
            stereo: m.stereo.clone(),
            scales: m.scales.clone(),
            grid: KeypointGrid::new(&m.keypoints, rig.width, rig.height),
            map_points: kf.map_points().to_vec(),
            pose_cw: kf.pose_cw(),
            reference_keyframe: Some(kf.id()),
            // Loop verification searches without a ratio test.
            descriptor_cell: None,
            distance_thresholds: m.distance_thresholds,
            thumbnail: None,
        }
    }

    /// Number of keypoints.
    pub fn len(&self) -> usize {
        self.features.len()
    }

    /// True when there is no keypoint.
    pub fn is_empty(&self) -> bool {
        self.features.is_empty()
    }

    /// Keypoints with a stereo depth.
    pub fn stereo_count(&self) -> usize {
        self.stereo.iter().flatten().count()
    }

    /// Keypoints matched to a map point.
    pub fn tracked_count(&self) -> usize {
        self.map_points.iter().flatten().count()
    }

    /// The stereo depth of keypoint `i`, when positive.
    pub fn depth(&self, i: usize) -> Option<f64> {
        self.stereo
            .get(i)
            .copied()
            .flatten()
            .map(|s| f64::from(s.depth))
            .filter(|d| *d > 0.0)
    }

    /// The world position of keypoint `i` from its stereo depth.
    pub fn unproject_world(&self, i: usize, rig: &CameraRig) -> Option<nalgebra::Vector3<f64>> {
        let depth = self.depth(i)?;
        let kp = self.features.keypoints.get(i)?;
        let camera_point = rig.unproject(f64::from(kp.x), f64::from(kp.y), depth);
        Some(self.pose_cw.inverse().transform_point(&camera_point))
    }

    /// The camera centre in world coordinates.
    pub fn camera_center(&self) -> nalgebra::Vector3<f64> {
        self.pose_cw.inverse().translation
    }

    /// What a keyframe made from this frame stores.
    pub fn measurements(&self) -> FrameMeasurements {
        FrameMeasurements {
            keypoints: self.features.keypoints.clone(),
            descriptors: self.features.descriptors.clone(),
            stereo: self.stereo.clone(),
            scales: self.scales.clone(),
            distance_thresholds: self.distance_thresholds,
        }
    }
}
