//! A map taken apart into plain, serialisable parts and put back together
//! (map storage: `crate::storage`).
//!
//! [`Map::to_parts`] copies everything the map holds: keyframes with their
//! measurements and slots, points with their observations and statistics,
//! the covisibility graph as it stands (weights and ordered connections,
//! which may lag the observations until the next `update_connections`),
//! the spanning tree, loop edges, the culled keyframes' relative poses,
//! the fused points' forwarding table and the id counters. The
//! descriptors are left in place but skipped by serde: storage writes them
//! in blocks of the precision chosen at save time and puts them back.
//!
//! [`Map::from_parts`] rebuilds the map and refuses parts that do not make
//! a consistent map ([`Map::check_invariants`]), naming what is wrong.

use std::collections::{BTreeMap, BTreeSet};

use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use crate::features::pyramid::ScaleTables;
use crate::features::{DescriptorSet, DistanceThresholds, Keypoint};
use crate::optim::Se3;

use super::counter::Counter;
use super::covisibility::CovisibilityNode;
use super::descriptor::PointDescriptor;
use super::ids::{KeyFrameId, MapPointId};
use super::invariants::InvariantViolation;
use super::keyframe::{FrameMeasurements, KeyFrame, StereoMeasurement};
use super::map_point::MapPoint;
use super::{CulledKeyFrame, Map};

/// A pose `T_cw` as `[qx, qy, qz, qw, tx, ty, tz]`.
pub type PoseParts = [f64; 7];

fn pose_to_parts(pose: &Se3) -> PoseParts {
    let q = pose.rotation.quaternion();
    let t = pose.translation;
    [q.i, q.j, q.k, q.w, t.x, t.y, t.z]
}

fn pose_from_parts(p: &PoseParts) -> Se3 {
    // A stored unit quaternion comes back bit for bit: no renormalisation.
    let q = UnitQuaternion::new_unchecked(Quaternion::new(p[3], p[0], p[1], p[2]));
    Se3::new(q, Vector3::new(p[4], p[5], p[6]))
}

/// ORB-SLAM3's per-level tables of a keyframe, as stored.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ScaleParts {
    /// `mvScaleFactor`.
    pub scale_factors: Vec<f32>,
    /// `mvInvScaleFactor`.
    pub inv_scale_factors: Vec<f32>,
    /// `mvLevelSigma2`.
    pub level_sigma2: Vec<f32>,
    /// `mvInvLevelSigma2`.
    pub inv_level_sigma2: Vec<f32>,
    /// `mnFeaturesPerLevel`.
    pub features_per_level: Vec<usize>,
}

/// A keyframe's graph node.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GraphParts {
    /// Shared-point counts with every keyframe it shares a point with.
    pub weights: Vec<(KeyFrameId, usize)>,
    /// Connected keyframes, by decreasing weight then id.
    pub ordered: Vec<(KeyFrameId, usize)>,
    /// Spanning-tree parent.
    pub parent: Option<KeyFrameId>,
    /// Whether it has been connected (is in the spanning tree).
    pub connected: bool,
    /// Loop edges.
    pub loop_edges: Vec<KeyFrameId>,
}

/// One keyframe.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct KeyFrameParts {
    /// Its id.
    pub id: KeyFrameId,
    /// Input frame it was made from.
    pub frame_index: usize,
    /// Timestamp (s).
    pub timestamp: f64,
    /// `T_cw`.
    pub pose_cw: PoseParts,
    /// Keypoints.
    pub keypoints: Vec<Keypoint>,
    /// Descriptors (written separately by storage).
    #[serde(skip, default = "empty_descriptors")]
    pub descriptors: DescriptorSet,
    /// Stereo measurements `(right_u, depth)` per keypoint.
    pub stereo: Vec<Option<(f32, f32)>>,
    /// Per-level tables.
    pub scales: ScaleParts,
    /// The descriptor-distance thresholds it was matched with.
    pub distance_thresholds: DistanceThresholds,
    /// The point each keypoint observes.
    pub slots: Vec<Option<MapPointId>>,
    /// Its graph node (`None` for a keyframe with none).
    pub graph: Option<GraphParts>,
}

fn empty_descriptors() -> DescriptorSet {
    DescriptorSet::Float {
        dim: 0,
        data: Vec::new(),
    }
}

fn empty_point_descriptor() -> PointDescriptor {
    PointDescriptor::Float(Vec::new().into())
}

/// One map point.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MapPointParts {
    /// Its id.
    pub id: MapPointId,
    /// World position.
    pub position: [f64; 3],
    /// Representative descriptor (written separately by storage).
    #[serde(skip, default = "empty_point_descriptor")]
    pub descriptor: PointDescriptor,
    /// Observing keyframe → keypoint index.
    pub observations: Vec<(KeyFrameId, usize)>,
    /// Keyframe that created it.
    pub first_keyframe: KeyFrameId,
    /// Keyframe of its scale distances.
    pub reference_keyframe: KeyFrameId,
    /// Mean viewing direction.
    pub normal: [f64; 3],
    /// Scale-invariance distances.
    pub min_distance: f64,
    /// Scale-invariance distances.
    pub max_distance: f64,
    /// ORB-SLAM3's `mnVisible`.
    pub visible: u32,
    /// ORB-SLAM3's `mnFound`.
    pub found: u32,
    /// ORB-SLAM3's `nObs`.
    pub weighted_observations: usize,
}

/// A culled keyframe's pose relative to its parent.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CulledParts {
    /// The culled keyframe.
    pub keyframe: KeyFrameId,
    /// Its parent when it was culled.
    pub parent: KeyFrameId,
    /// `T_c,parent`.
    pub relative_pose: PoseParts,
}

/// A whole map in parts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MapParts {
    /// First id it issues.
    pub id_base: u64,
    /// Next keyframe id.
    pub next_keyframe: u64,
    /// Next point id.
    pub next_point: u64,
    /// Keyframe id ranges of absorbed maps, `[start, end)`.
    pub closed_keyframe_ranges: Vec<(u64, u64)>,
    /// Live keyframes, in id order.
    pub keyframes: Vec<KeyFrameParts>,
    /// Live points, in id order.
    pub points: Vec<MapPointParts>,
    /// Culled keyframes.
    pub culled: Vec<CulledParts>,
    /// Fused points: old id → the point it was fused into.
    pub replaced: Vec<(MapPointId, MapPointId)>,
}

impl Map {
    /// The map in parts (see the module's docs).
    pub fn to_parts(&self) -> MapParts {
        let keyframes = self
            .keyframes
            .values()
            .map(|kf| {
                let m = &kf.measurements;
                KeyFrameParts {
                    id: kf.id(),
                    frame_index: kf.frame_index,
                    timestamp: kf.timestamp,
                    pose_cw: pose_to_parts(&kf.pose_cw()),
                    keypoints: m.keypoints.clone(),
                    descriptors: m.descriptors.clone(),
                    stereo: m
                        .stereo
                        .iter()
                        .map(|s| s.map(|s| (s.right_u, s.depth)))
                        .collect(),
                    scales: ScaleParts {
                        scale_factors: m.scales.scale_factors.clone(),
                        inv_scale_factors: m.scales.inv_scale_factors.clone(),
                        level_sigma2: m.scales.level_sigma2.clone(),
                        inv_level_sigma2: m.scales.inv_level_sigma2.clone(),
                        features_per_level: m.scales.features_per_level.clone(),
                    },
                    distance_thresholds: m.distance_thresholds,
                    slots: kf.map_points().to_vec(),
                    graph: self.covisibility.get(&kf.id()).map(|n| GraphParts {
                        weights: n.weights.iter().map(|(k, w)| (*k, *w)).collect(),
                        ordered: n.ordered.clone(),
                        parent: n.parent,
                        connected: n.connected,
                        loop_edges: n.loop_edges.iter().copied().collect(),
                    }),
                }
            })
            .collect();
        let points = self
            .points
            .values()
            .map(|p| MapPointParts {
                id: p.id(),
                position: [p.position.x, p.position.y, p.position.z],
                descriptor: p.descriptor.clone(),
                observations: p.observations.iter().map(|(k, i)| (*k, *i)).collect(),
                first_keyframe: p.first_keyframe,
                reference_keyframe: p.reference_keyframe,
                normal: [p.normal.x, p.normal.y, p.normal.z],
                min_distance: p.min_distance,
                max_distance: p.max_distance,
                visible: p.visible.get(),
                found: p.found.get(),
                weighted_observations: p.weighted_observations,
            })
            .collect();
        MapParts {
            id_base: self.id_base,
            next_keyframe: self.next_keyframe,
            next_point: self.next_point,
            closed_keyframe_ranges: self
                .closed_keyframe_ranges
                .iter()
                .map(|r| (r.start, r.end))
                .collect(),
            keyframes,
            points,
            culled: self
                .culled
                .iter()
                .map(|(k, c)| CulledParts {
                    keyframe: *k,
                    parent: c.parent,
                    relative_pose: pose_to_parts(&c.relative_pose),
                })
                .collect(),
            replaced: self.replaced.iter().map(|(a, b)| (*a, *b)).collect(),
        }
    }

    /// Rebuilds a map from its parts; parts that do not make a consistent
    /// map are refused with the first inconsistency found.
    pub fn from_parts(parts: MapParts) -> Result<Map, InvariantViolation> {
        let mut map = Map {
            next_keyframe: parts.next_keyframe,
            next_point: parts.next_point,
            id_base: parts.id_base,
            closed_keyframe_ranges: parts
                .closed_keyframe_ranges
                .iter()
                .map(|(a, b)| *a..*b)
                .collect(),
            ..Map::default()
        };
        if map.id_base > map.next_keyframe || map.id_base > map.next_point {
            return Err(InvariantViolation::IdBaseAboveCounters {
                base: map.id_base,
                next_keyframe: map.next_keyframe,
                next_point: map.next_point,
            });
        }
        let mut children: BTreeMap<KeyFrameId, BTreeSet<KeyFrameId>> = BTreeMap::new();
        for kf in parts.keyframes {
            let measurements = FrameMeasurements {
                keypoints: kf.keypoints,
                descriptors: kf.descriptors,
                stereo: kf
                    .stereo
                    .iter()
                    .map(|s| s.map(|(right_u, depth)| StereoMeasurement { right_u, depth }))
                    .collect(),
                scales: ScaleTables {
                    scale_factors: kf.scales.scale_factors,
                    inv_scale_factors: kf.scales.inv_scale_factors,
                    level_sigma2: kf.scales.level_sigma2,
                    inv_level_sigma2: kf.scales.inv_level_sigma2,
                    features_per_level: kf.scales.features_per_level,
                },
                distance_thresholds: kf.distance_thresholds,
            };
            let mut keyframe = KeyFrame::new(
                kf.id,
                kf.frame_index,
                kf.timestamp,
                pose_from_parts(&kf.pose_cw),
                measurements,
            );
            if kf.slots.len() != keyframe.map_points().len() {
                return Err(InvariantViolation::SlotCountMismatch {
                    keyframe: kf.id,
                    slots: kf.slots.len(),
                    keypoints: keyframe.map_points().len(),
                });
            }
            for (i, slot) in kf.slots.iter().enumerate() {
                keyframe.set_map_point(i, *slot);
            }
            if let Some(g) = kf.graph {
                if let Some(parent) = g.parent {
                    children.entry(parent).or_default().insert(kf.id);
                }
                map.covisibility.insert(
                    kf.id,
                    CovisibilityNode {
                        weights: g.weights.into_iter().collect(),
                        ordered: g.ordered,
                        parent: g.parent,
                        children: BTreeSet::new(),
                        connected: g.connected,
                        loop_edges: g.loop_edges.into_iter().collect(),
                    },
                );
            }
            if map.keyframes.insert(kf.id, keyframe).is_some() {
                return Err(InvariantViolation::DuplicateKeyFrame { keyframe: kf.id });
            }
        }
        for (parent, kids) in children {
            map.covisibility.entry(parent).or_default().children = kids;
        }
        for p in parts.points {
            let [x, y, z] = p.position;
            let mut point =
                MapPoint::new(p.id, Vector3::new(x, y, z), p.descriptor, p.first_keyframe);
            point.observations = p.observations.into_iter().collect();
            point.reference_keyframe = p.reference_keyframe;
            let [nx, ny, nz] = p.normal;
            point.normal = Vector3::new(nx, ny, nz);
            point.min_distance = p.min_distance;
            point.max_distance = p.max_distance;
            point.visible = Counter::new(p.visible);
            point.found = Counter::new(p.found);
            point.weighted_observations = p.weighted_observations;
            if map.points.insert(p.id, point).is_some() {
                return Err(InvariantViolation::DuplicateMapPoint { point: p.id });
            }
        }
        for c in parts.culled {
            map.culled.insert(
                c.keyframe,
                CulledKeyFrame {
                    parent: c.parent,
                    relative_pose: pose_from_parts(&c.relative_pose),
                },
            );
        }
        map.replaced = parts.replaced.into_iter().collect();
        map.check_invariants()?;
        Ok(map)
    }
}
