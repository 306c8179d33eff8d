//! The map: keyframes, map points with float (or binary) descriptors, the
//! covisibility graph and the spanning tree.
//!
//! Entities refer to each other by id ([`KeyFrameId`], [`MapPointId`]), never
//! by pointer; the [`Map`] owns them all in ordered maps, so iteration is
//! deterministic. Every operation that changes an association keeps both
//! sides consistent (a keyframe slot and the point's observation list).
//!
//! # Locking rules
//!
//! Tracking and local mapping run on separate threads and share one
//! [`SharedMap`], an `Arc<RwLock<Map>>`. No `unsafe` is involved; the borrow
//! checker rules out data races, and these rules keep the threads from
//! waiting on each other's heavy work:
//!
//! - **Tracking** (`Tracker::track`) holds the **read** lock for everything
//!   it does to a frame: motion model, reference keyframe, relocalisation,
//!   local-map search, pose refinement, the keyframe decision. The
//!   visibility statistics it keeps on points ([`MapPoint::visible`],
//!   [`MapPoint::found`]) are atomic [`Counter`]s, bumped through `&Map`.
//!   It takes the **write** lock only to initialise a map or insert a
//!   keyframe, after releasing the read lock; what changed in between
//!   (points fused or culled) is resolved again at insertion.
//! - **Local mapping** (`LocalMapper::process_keyframe`) works as snapshot →
//!   compute → apply for each step: it reads under the read lock
//!   (triangulation and fusion candidates; the BA problem, a detached copy),
//!   solves the BA with no lock held, and applies each result under a short
//!   write lock, skipping keyframes and points culled or fused since the
//!   snapshot. Refreshing the new keyframe's points and culling take short
//!   write locks.
//! - Nobody holds a lock across a channel operation or while waiting for
//!   another thread, and a guard is never held across a call that takes the
//!   same lock again.

mod absorb;
mod counter;
mod covisibility;
mod culling;
mod descriptor;
mod error;
mod excerpt;
mod ids;
mod invariants;
mod keyframe;
mod map_point;
mod observation;
mod parts;
#[cfg(test)]
pub(crate) mod tests_support;

use std::collections::BTreeMap;
use std::sync::{Arc, RwLock};

use nalgebra::Vector3;

pub use counter::Counter;
pub use covisibility::COVISIBILITY_THRESHOLD;
pub use culling::{PointCullingReport, MIN_FOUND_RATIO, REDUNDANT_FRACTION};
pub use descriptor::{most_representative, PointDescriptor};
pub use error::{MapError, Result};
pub use ids::{KeyFrameId, MapPointId};
pub use invariants::InvariantViolation;
pub use keyframe::{FrameMeasurements, KeyFrame, StereoMeasurement};
pub use map_point::MapPoint;
pub use observation::keypoint_observation;
pub use parts::{
    CulledParts, GraphParts, KeyFrameParts, MapParts, MapPointParts, PoseParts, ScaleParts,
};

use crate::optim::{LieGroup, Se3};
use covisibility::CovisibilityNode;

/// A map shared between threads.
pub type SharedMap = Arc<RwLock<Map>>;

/// Where a culled keyframe was, relative to its spanning-tree parent, so the
/// poses of frames tracked against it can still be recovered.
#[derive(Debug, Clone, Copy)]
pub(crate) struct CulledKeyFrame {
    parent: KeyFrameId,
    /// `T_c,parent`: the culled keyframe's pose relative to its parent.
    relative_pose: Se3,
}

/// Keyframes, map points and their graph.
#[derive(Debug, Default)]
pub struct Map {
    keyframes: BTreeMap<KeyFrameId, KeyFrame>,
    points: BTreeMap<MapPointId, MapPoint>,
    covisibility: BTreeMap<KeyFrameId, CovisibilityNode>,
    culled: BTreeMap<KeyFrameId, CulledKeyFrame>,
    replaced: BTreeMap<MapPointId, MapPointId>,
    next_keyframe: u64,
    next_point: u64,
    /// First id this map issues (keyframes and points alike); see
    /// [`Map::with_id_base`].
    id_base: u64,
    /// Keyframe ids issued by maps absorbed into this one, or by this map
    /// before it absorbed one with a higher base ([`Map::absorb`]).
    closed_keyframe_ranges: Vec<std::ops::Range<u64>>,
}

impl Map {
    /// An empty map.
    pub fn new() -> Self {
        Self::default()
    }

    /// An empty map whose keyframe and point ids start at `base`. The
    /// maps of an atlas get disjoint bases, so that one can absorb another
    /// ([`Map::absorb`]) and every id that tracking, local mapping and the
    /// frame records hold stays valid.
    pub fn with_id_base(base: u64) -> Self {
        Self {
            next_keyframe: base,
            next_point: base,
            id_base: base,
            ..Self::default()
        }
    }

    /// Every keyframe id range this map has issued (live or culled ids).
    pub(crate) fn issued_keyframe_ranges(&self) -> Vec<std::ops::Range<u64>> {
        let mut ranges = self.closed_keyframe_ranges.clone();
        ranges.push(self.id_base..self.next_keyframe);
        ranges
    }

    /// Wraps a map for sharing between threads.
    pub fn into_shared(self) -> SharedMap {
        Arc::new(RwLock::new(self))
    }

    /// Live keyframes, in id order.
    pub fn keyframes(&self) -> impl Iterator<Item = &KeyFrame> {
        self.keyframes.values()
    }

    /// Live map points, in id order.
    pub fn map_points(&self) -> impl Iterator<Item = &MapPoint> {
        self.points.values()
    }

    /// Number of live keyframes.
    pub fn keyframe_count(&self) -> usize {
        self.keyframes.len()
    }

    /// Number of live map points.
    pub fn map_point_count(&self) -> usize {
        self.points.len()
    }

    /// A live keyframe.
    pub fn keyframe(&self, id: KeyFrameId) -> Result<&KeyFrame> {
        self.keyframes.get(&id).ok_or(MapError::UnknownKeyFrame(id))
    }

    /// A live keyframe, mutably (its pose; associations change through the map).
    pub fn keyframe_mut(&mut self, id: KeyFrameId) -> Result<&mut KeyFrame> {
        self.keyframes
            .get_mut(&id)
            .ok_or(MapError::UnknownKeyFrame(id))
    }

    /// A live map point.
    pub fn map_point(&self, id: MapPointId) -> Result<&MapPoint> {
        self.points.get(&id).ok_or(MapError::UnknownMapPoint(id))
    }

    /// A live map point, mutably (position, counters).
    pub fn map_point_mut(&mut self, id: MapPointId) -> Result<&mut MapPoint> {
        self.points
            .get_mut(&id)
            .ok_or(MapError::UnknownMapPoint(id))
    }

    /// Adds a keyframe with no associations yet.
    pub fn add_keyframe(
        &mut self,
        frame_index: usize,
        timestamp: f64,
        pose_cw: Se3,
        measurements: FrameMeasurements,
    ) -> Result<KeyFrameId> {
        measurements.validate()?;
        let id = KeyFrameId(self.next_keyframe);
        self.next_keyframe += 1;
        self.keyframes.insert(
            id,
            KeyFrame::new(id, frame_index, timestamp, pose_cw, measurements),
        );
        self.covisibility.insert(id, CovisibilityNode::default());
        Ok(id)
    }

    /// Adds a point created by `first_keyframe`, with no observation yet.
    pub fn add_map_point(
        &mut self,
        position: Vector3<f64>,
        descriptor: PointDescriptor,
        first_keyframe: KeyFrameId,
    ) -> Result<MapPointId> {
        self.keyframe(first_keyframe)?;
        let id = MapPointId(self.next_point);
        self.next_point += 1;
        self.points
            .insert(id, MapPoint::new(id, position, descriptor, first_keyframe));
        Ok(id)
    }

    /// Records that keypoint `index` of `keyframe` observes `point`.
    pub fn add_observation(
        &mut self,
        point: MapPointId,
        keyframe: KeyFrameId,
        index: usize,
    ) -> Result<()> {
        let kf = self
            .keyframes
            .get_mut(&keyframe)
            .ok_or(MapError::UnknownKeyFrame(keyframe))?;
        kf.check_index(index)?;
        let p = self
            .points
            .get_mut(&point)
            .ok_or(MapError::UnknownMapPoint(point))?;
        match kf.map_point(index) {
            Some(existing) if existing != point => {
                return Err(MapError::KeypointTaken {
                    keyframe,
                    index,
                    existing,
                })
            }
            Some(_) => return Ok(()),
            None => {}
        }
        if let Some(old_index) = p.observations.insert(keyframe, index) {
            // The point moves to another keypoint of the same keyframe.
            kf.set_map_point(old_index, None);
            p.weighted_observations -= observation_weight(kf, old_index);
        }
        kf.set_map_point(index, Some(point));
        p.weighted_observations += observation_weight(kf, index);
        Ok(())
    }

    /// Removes `keyframe`'s observation of `point`. A point left with two
    /// weighted observations or fewer is erased, as in ORB-SLAM3.
    pub fn erase_observation(&mut self, point: MapPointId, keyframe: KeyFrameId) -> Result<()> {
        let p = self
            .points
            .get_mut(&point)
            .ok_or(MapError::UnknownMapPoint(point))?;
        let Some(index) = p.observations.remove(&keyframe) else {
            return Ok(());
        };
        if let Some(kf) = self.keyframes.get_mut(&keyframe) {
            kf.set_map_point(index, None);
            p.weighted_observations = p
                .weighted_observations
                .saturating_sub(observation_weight(kf, index));
        }
        if p.reference_keyframe == keyframe {
            if let Some(first) = p.observations.keys().next() {
                p.reference_keyframe = *first;
            }
        }
        if p.weighted_observations <= 2 {
            self.erase_map_point(point);
        }
        Ok(())
    }

    /// Erases a point and every keyframe slot that refers to it.
    pub fn erase_map_point(&mut self, point: MapPointId) {
        if let Some(p) = self.points.remove(&point) {
            for (kf, index) in p.observations {
                if let Some(kf) = self.keyframes.get_mut(&kf) {
                    kf.set_map_point(index, None);
                }
            }
        }
    }

    /// Fuses `old` into `new` (ORB-SLAM3's `Replace`): `new` takes over the
    /// observations of keyframes that did not already see it, and the
    /// visibility counters. Later lookups of `old` resolve to `new`.
    pub fn replace_map_point(&mut self, old: MapPointId, new: MapPointId) -> Result<()> {
        if old == new {
            return Ok(());
        }
        self.map_point(new)?;
        let old_point = self
            .points
            .remove(&old)
            .ok_or(MapError::UnknownMapPoint(old))?;
        for (kf, index) in &old_point.observations {
            let already_sees_new = self
                .points
                .get(&new)
                .is_some_and(|p| p.observations.contains_key(kf));
            if let Some(keyframe) = self.keyframes.get_mut(kf) {
                keyframe.set_map_point(*index, None);
            }
            if !already_sees_new {
                self.add_observation(new, *kf, *index)?;
            }
        }
        if let Some(p) = self.points.get_mut(&new) {
            p.visible.add(old_point.visible.get());
            p.found.add(old_point.found.get());
        }
        self.replaced.insert(old, new);
        self.update_descriptor(new);
        self.update_normal_and_depth(new);
        Ok(())
    }

    /// The live point `id` stands for: itself, or what it was fused into.
    pub fn resolve_point(&self, id: MapPointId) -> Option<MapPointId> {
        let mut current = id;
        for _ in 0..=self.replaced.len() {
            if self.points.contains_key(&current) {
                return Some(current);
            }
            current = *self.replaced.get(&current)?;
        }
        None
    }

    /// Recomputes a point's representative descriptor from its observations.
    pub fn update_descriptor(&mut self, point: MapPointId) {
        let Some(p) = self.points.get(&point) else {
            return;
        };
        let rows: Vec<_> = p
            .observations
            .iter()
            .filter_map(|(kf, i)| self.keyframes.get(kf)?.measurements.descriptors.row(*i))
            .collect();
        let best = most_representative(&rows).and_then(|i| rows.get(i));
        let Some(descriptor) = best.map(PointDescriptor::from_ref) else {
            return;
        };
        if let Some(p) = self.points.get_mut(&point) {
            p.descriptor = descriptor;
        }
    }

    /// Recomputes a point's mean viewing direction and its scale-invariance
    /// distances from its reference keyframe (ORB-SLAM3's `UpdateNormalAndDepth`).
    pub fn update_normal_and_depth(&mut self, point: MapPointId) {
        let Some(p) = self.points.get(&point) else {
            return;
        };
        let mut normal = Vector3::zeros();
        let mut n = 0usize;
        for kf in p.observations.keys() {
            if let Some(kf) = self.keyframes.get(kf) {
                let ray = p.position - kf.camera_center();
                let norm = ray.norm();
                if norm > 0.0 {
                    normal += ray / norm;
                    n += 1;
                }
            }
        }
        let reference = self.keyframes.get(&p.reference_keyframe).and_then(|kf| {
            let index = *p.observations.get(&kf.id())?;
            let octave = kf.measurements.keypoints.get(index)?.octave.max(0) as usize;
            let scales = &kf.measurements.scales;
            let level_scale = f64::from(*scales.scale_factors.get(octave)?);
            let top_scale = f64::from(*scales.scale_factors.last()?);
            let distance = (p.position - kf.camera_center()).norm();
            Some((distance * level_scale, distance * level_scale / top_scale))
        });
        if let Some(p) = self.points.get_mut(&point) {
            if n > 0 {
                p.normal = (normal / n as f64).normalize();
            }
            if let Some((max_distance, min_distance)) = reference {
                p.max_distance = max_distance;
                p.min_distance = min_distance;
            }
        }
    }

    /// Removes a keyframe (ORB-SLAM3's `SetBadFlag`): its observations, its
    /// graph edges (children get new parents), remembering its pose relative
    /// to its parent (for a keyframe never connected, which has none yet, the
    /// newest older keyframe in the spanning tree) for [`Map::pose_cw_of`],
    /// so that works for every keyframe the map ever held. The map's first
    /// keyframe stays.
    pub fn erase_keyframe(&mut self, keyframe: KeyFrameId) -> Result<()> {
        if self.keyframes.keys().next() == Some(&keyframe) {
            return Ok(());
        }
        let kf = self.keyframe(keyframe)?;
        let observed: Vec<MapPointId> = kf.observed_points().map(|(_, p)| p).collect();
        let pose_cw = kf.pose_cw();
        for point in observed {
            self.erase_observation(point, keyframe)?;
        }
        let parent = self.detach_from_graph(keyframe);
        if let Some(parent) = parent {
            if let Ok(parent_pose) = self.pose_cw_of(parent) {
                self.culled.insert(
                    keyframe,
                    CulledKeyFrame {
                        parent,
                        relative_pose: pose_cw.compose(&parent_pose.inverse()),
                    },
                );
            }
        }
        self.keyframes.remove(&keyframe);
        Ok(())
    }

    /// The median depth of the points a live keyframe observes, in its
    /// camera (ORB-SLAM3's `KeyFrame::ComputeSceneMedianDepth`); `None`
    /// without a point in front of it.
    pub fn median_scene_depth(&self, keyframe: KeyFrameId) -> Option<f64> {
        let kf = self.keyframes.get(&keyframe)?;
        let pose = kf.pose_cw();
        let mut depths: Vec<f64> = kf
            .observed_points()
            .filter_map(|(_, p)| self.points.get(&p))
            .map(|p| pose.transform_point(&p.position).z)
            .filter(|z| z.is_finite() && *z > 0.0)
            .collect();
        crate::stats::upper_median(&mut depths)
    }

    /// The pose `T_cw` of a keyframe, live or culled (through its parents).
    pub fn pose_cw_of(&self, keyframe: KeyFrameId) -> Result<Se3> {
        let mut relative = Se3::identity();
        let mut current = keyframe;
        for _ in 0..=self.culled.len() {
            if let Some(kf) = self.keyframes.get(&current) {
                return Ok(relative.compose(&kf.pose_cw()));
            }
            let culled = self
                .culled
                .get(&current)
                .ok_or(MapError::UnknownKeyFrame(keyframe))?;
            relative = relative.compose(&culled.relative_pose);
            current = culled.parent;
        }
        Err(MapError::UnknownKeyFrame(keyframe))
    }
}

/// ORB-SLAM3 counts an observation with a stereo measurement twice.
fn observation_weight(kf: &KeyFrame, index: usize) -> usize {
    match kf.measurements.stereo.get(index) {
        Some(Some(_)) => 2,
        _ => 1,
    }
}
