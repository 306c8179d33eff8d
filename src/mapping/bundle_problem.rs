//! The one builder of bundle-adjustment problems from the map, shared by
//! local BA ([`super::bundle`]) and the global BA after a loop
//! (`loop_closing::global_ba`): the caller chooses the keyframes (each free
//! or fixed) and the points; every observation of a chosen point by a
//! chosen keyframe enters the problem as the one measurement policy says
//! ([`crate::map::FrameMeasurements::observation`]).

use std::collections::BTreeMap;

use crate::camera::CameraRig;
use crate::map::{KeyFrameId, Map, MapPointId};
use crate::optim::local_ba::{BaObservation, BundleProblem};

/// A detached BA problem with the ids to write its solution back.
#[derive(Debug)]
pub struct MapBundle {
    /// The problem (poses, points, observations).
    pub problem: BundleProblem,
    /// Pose index → keyframe.
    pub keyframes: Vec<KeyFrameId>,
    /// Keyframe → pose index.
    pub pose_index: BTreeMap<KeyFrameId, usize>,
    /// Point index → map point.
    pub points: Vec<MapPointId>,
    /// Observation index → (point, keyframe).
    pub links: Vec<(MapPointId, KeyFrameId)>,
}

/// Builds the problem over `keyframes` (`(id, fixed)`, in pose order;
/// culled ones skipped) and `points` (in order; a point culled or seen by
/// none of the keyframes is left out). `None` when no observation is left.
pub fn build_map_bundle(
    map: &Map,
    rig: &CameraRig,
    keyframes: impl IntoIterator<Item = (KeyFrameId, bool)>,
    points: impl IntoIterator<Item = MapPointId>,
) -> Option<MapBundle> {
    let mut pose_index = BTreeMap::new();
    let mut ids = Vec::new();
    let mut poses = Vec::new();
    let mut fixed = Vec::new();
    for (kf, is_fixed) in keyframes {
        let Ok(k) = map.keyframe(kf) else { continue };
        if pose_index.insert(kf, poses.len()).is_some() {
            continue;
        }
        ids.push(kf);
        poses.push(k.pose_cw());
        fixed.push(is_fixed);
    }
    let mut kept = Vec::new();
    let mut positions = Vec::new();
    let mut observations = Vec::new();
    let mut links = Vec::new();
    for p in points {
        let Ok(point) = map.map_point(p) else {
            continue;
        };
        let start = observations.len();
        for (kf, index) in point.observations() {
            let Some(&pose) = pose_index.get(kf) else {
                continue;
            };
            let Some(obs) = map
                .keyframe(*kf)
                .ok()
                .and_then(|k| k.measurements.observation(*index, rig.stereo_depth_limit()))
            else {
                continue;
            };
            observations.push(BaObservation {
                pose,
                point: kept.len(),
                obs,
            });
            links.push((p, *kf));
        }
        if observations.len() > start {
            kept.push(p);
            positions.push(point.position);
        }
    }
    if observations.is_empty() {
        return None;
    }
    Some(MapBundle {
        problem: BundleProblem {
            camera: rig.camera,
            poses,
            fixed,
            points: positions,
            observations,
        },
        keyframes: ids,
        pose_index,
        points: kept,
        links,
    })
}
