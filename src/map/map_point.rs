//! Map points: a position, the keyframes observing it, a representative
//! descriptor, and the viewing normal and scale-invariance distances.

use std::collections::BTreeMap;

use nalgebra::Vector3;

use super::counter::Counter;
use super::descriptor::PointDescriptor;
use super::ids::{KeyFrameId, MapPointId};

/// A 3-D point in the map.
#[derive(Debug, Clone)]
pub struct MapPoint {
    id: MapPointId,
    /// World position.
    pub position: Vector3<f64>,
    /// The representative descriptor (least median distance to the others).
    pub descriptor: PointDescriptor,
    /// Observing keyframes → keypoint index in that keyframe.
    pub(super) observations: BTreeMap<KeyFrameId, usize>,
    /// Keyframe that created it.
    pub first_keyframe: KeyFrameId,
    /// Keyframe used for the scale distances (the first, or a later one if it goes).
    pub reference_keyframe: KeyFrameId,
    /// Mean unit viewing direction from the observing cameras to the point.
    pub normal: Vector3<f64>,
    /// Smallest distance at which the point is expected to be detected.
    pub min_distance: f64,
    /// Largest distance at which the point is expected to be detected.
    pub max_distance: f64,
    /// Times it was predicted visible in a tracked frame (ORB-SLAM3's
    /// `mnVisible`); tracking bumps it under the map's read lock.
    pub visible: Counter,
    /// Times it was then matched (ORB-SLAM3's `mnFound`); bumped like `visible`.
    pub found: Counter,
    /// Observation count, stereo observations counting twice (ORB-SLAM3's `nObs`).
    pub(super) weighted_observations: usize,
}

impl MapPoint {
    pub(super) fn new(
        id: MapPointId,
        position: Vector3<f64>,
        descriptor: PointDescriptor,
        first_keyframe: KeyFrameId,
    ) -> Self {
        Self {
            id,
            position,
            descriptor,
            observations: BTreeMap::new(),
            first_keyframe,
            reference_keyframe: first_keyframe,
            normal: Vector3::zeros(),
            min_distance: 0.0,
            max_distance: f64::INFINITY,
            visible: Counter::new(1),
            found: Counter::new(1),
            weighted_observations: 0,
        }
    }

    /// Its id.
    pub fn id(&self) -> MapPointId {
        self.id
    }

    /// Observing keyframes with the keypoint index, in id order.
    pub fn observations(&self) -> &BTreeMap<KeyFrameId, usize> {
        &self.observations
    }

    /// Observations, stereo ones counting twice.
    pub fn observation_count(&self) -> usize {
        self.weighted_observations
    }

    /// `found / visible` (ORB-SLAM3's `GetFoundRatio`).
    pub fn found_ratio(&self) -> f64 {
        f64::from(self.found.get()) / f64::from(self.visible.get().max(1))
    }

    /// The pyramid level at which the point should appear from `distance`
    /// (ORB-SLAM3's `PredictScale`), clamped to `[0, n_levels − 1]`.
    pub fn predict_octave(&self, distance: f64, scale_factor: f64, n_levels: usize) -> usize {
        if distance.is_nan() || distance <= 0.0 || !self.max_distance.is_finite() {
            return 0;
        }
        let ratio = self.max_distance / distance;
        // The small margin keeps a point seen from its creation distance at its
        // own octave despite f32 scale tables (ORB-SLAM3 would round up).
        let level = (ratio.ln() / scale_factor.ln() - 1e-6).ceil();
        level.clamp(0.0, n_levels.saturating_sub(1) as f64) as usize
    }

    /// Whether `distance` lies in the scale-invariance range (ORB-SLAM3 widens
    /// it by 0.8 / 1.2 when searching).
    pub fn in_distance_range(&self, distance: f64) -> bool {
        distance >= 0.8 * self.min_distance && distance <= 1.2 * self.max_distance
    }
}
