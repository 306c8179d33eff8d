//! Loop correction on the map, as ORB-SLAM3's `LoopClosing::CorrectLoop`:
//! SE(3) for a stereo or RGB-D map; Sim(3) for a monocular one, whose
//! query side is also scaled to the loop side (the poses `T ← (R, t/s)`
//! of the corrected similarities, the points through them):
//!
//! 1. the query keyframe and its covisible keyframes move by the loop's
//!    correction `C` (`T_kw ← T_kw·C`), and the points they observe with
//!    them (`X ← C⁻¹·X`);
//! 2. loop fusion: the query's matches take the loop group's points, and the
//!    group's points projected into the moved keyframes replace their
//!    duplicates (`SearchAndFuse`);
//! 3. the moved keyframes' connections are refreshed; the links they gained
//!    to outside keyframes are the loop connections;
//! 4. the essential graph is optimised (the loop keyframe fixed) and every
//!    point follows its reference keyframe;
//! 5. a loop edge joins the query and the loop keyframe.

use std::collections::{BTreeMap, BTreeSet};

use nalgebra::Vector3;

use crate::camera::CameraRig;
use crate::camera::Sensor;
use crate::error::{MapContext, SlamError};
use crate::map::{KeyFrameId, Map, MapPointId};
use crate::mapping::{apply_fusion_candidates, plan_fusion_into, refresh_observed_points};
use crate::optim::{LieGroup, Se3, Sim3};

use super::detector::AcceptedLoop;
use super::drift::pose_difference;
use super::essential_graph::{optimise_essential_graph, EssentialGraphInput};
use super::side_scale::{scaled_correction, side_scale};

/// What a correction did.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct LoopCorrection {
    /// How far the query keyframe's camera centre moved (metres).
    pub correction_m: f64,
    /// How far it turned (degrees).
    pub correction_deg: f64,
    /// Keyframes moved with the query before the graph optimisation.
    pub moved_keyframes: usize,
    /// Points fused or given an observation.
    pub fused: usize,
    /// Essential-graph edges.
    pub graph_edges: usize,
    /// Essential-graph iterations.
    pub graph_iterations: usize,
    /// Time of the essential-graph optimisation (ms).
    pub graph_ms: f64,
}

/// The scale of the query's side of a monocular loop over the loop side's
/// ([`side_scale`] on the one map); 1 with too few pairs.
fn loop_scale(map: &Map, accepted: &AcceptedLoop, query_pose: &Se3) -> f64 {
    side_scale(
        map,
        accepted.query,
        query_pose,
        &accepted.matches,
        map,
        &accepted.pose_cw,
    )
    .unwrap_or(1.0)
}

/// Corrects `map` with an accepted loop (see the module's docs; a
/// monocular map's in Sim(3), as ORB-SLAM3's `CorrectLoop`).
pub fn correct_loop(
    map: &mut Map,
    accepted: &AcceptedLoop,
    rig: &CameraRig,
) -> Result<LoopCorrection, SlamError> {
    let query_pose = map.pose_cw_of(accepted.query).in_stage("loop correction")?;
    let correction = query_pose.inverse().compose(&accepted.pose_cw);
    // Monocular: the query side's scale over the loop side's, and the
    // correction as a similarity (ORB-SLAM3's `mg2oLoopScw`).
    let similarity = (rig.sensor == Sensor::Monocular).then(|| {
        let scale = loop_scale(map, accepted, &query_pose);
        scaled_correction(&query_pose, &accepted.pose_cw, scale)
    });
    let (correction_m, correction_deg) = pose_difference(&query_pose, &accepted.pose_cw);
    let group: BTreeSet<KeyFrameId> = accepted.group.iter().copied().collect();

    // 1. Move the query's neighbourhood and its points.
    let mut moved: Vec<KeyFrameId> = vec![accepted.query];
    moved.extend(
        map.best_covisible(accepted.query, usize::MAX)
            .into_iter()
            .filter(|k| !group.contains(k)),
    );
    let previous_neighbours: BTreeMap<KeyFrameId, BTreeSet<KeyFrameId>> = moved
        .iter()
        .map(|k| (*k, map.best_covisible(*k, usize::MAX).into_iter().collect()))
        .collect();
    let mut uncorrected = BTreeMap::new();
    let mut corrected_sim3 = BTreeMap::new();
    let mut points: BTreeSet<MapPointId> = BTreeSet::new();
    for k in &moved {
        let kf = map.keyframe_mut(*k).in_stage("loop correction")?;
        let pose = kf.pose_cw();
        uncorrected.insert(*k, pose);
        match &similarity {
            Some(c) => {
                let corrected = Sim3::from_se3(&pose).compose(c);
                corrected_sim3.insert(*k, corrected);
                kf.set_pose_cw(corrected.to_se3_unscaled());
            }
            None => kf.set_pose_cw(pose.compose(&correction)),
        }
        points.extend(kf.observed_points().map(|(_, p)| p));
    }
    let inverse = correction.inverse();
    let similarity_inverse = similarity.map(|c| c.inverse());
    for p in &points {
        if let Ok(point) = map.map_point_mut(*p) {
            point.position = match &similarity_inverse {
                Some(c) => c.transform_point(&point.position),
                None => inverse.transform_point(&point.position),
            };
        }
    }

    // 2. Loop fusion.
    let mut fused = 0;
    for (i, matched) in accepted.matches.iter().enumerate() {
        let Some(loop_point) = matched.and_then(|p| map.resolve_point(p)) else {
            continue;
        };
        let own = map
            .keyframe(accepted.query)
            .ok()
            .and_then(|kf| kf.map_point(i))
            .and_then(|p| map.resolve_point(p));
        match own {
            Some(p) if p == loop_point => {}
            Some(p) => {
                map.replace_map_point(p, loop_point)
                    .in_stage("loop fusion")?;
                fused += 1;
            }
            None => {
                let seen = map
                    .map_point(loop_point)
                    .is_ok_and(|mp| mp.observations().contains_key(&accepted.query));
                if !seen {
                    map.add_observation(loop_point, accepted.query, i)
                        .in_stage("loop fusion")?;
                    fused += 1;
                }
            }
        }
    }
    let group_points: Vec<MapPointId> = {
        let mut set = BTreeSet::new();
        for k in &group {
            if let Ok(kf) = map.keyframe(*k) {
                set.extend(
                    kf.observed_points()
                        .filter_map(|(_, p)| map.resolve_point(p)),
                );
            }
        }
        set.into_iter().collect()
    };
    let planned = plan_fusion_into(map, &moved, &group_points, rig);
    fused += apply_fusion_candidates(map, planned)?;

    // 3. Connections and the loop's new links.
    let mut loop_connections: BTreeMap<KeyFrameId, BTreeSet<KeyFrameId>> = BTreeMap::new();
    let moved_set: BTreeSet<KeyFrameId> = moved.iter().copied().collect();
    for k in &moved {
        refresh_observed_points(map, *k);
        map.update_connections(*k);
    }
    for k in &moved {
        let before = previous_neighbours.get(k).cloned().unwrap_or_default();
        let links: BTreeSet<KeyFrameId> = map
            .best_covisible(*k, usize::MAX)
            .into_iter()
            .filter(|n| !before.contains(n) && !moved_set.contains(n))
            .collect();
        if !links.is_empty() {
            loop_connections.insert(*k, links);
        }
    }
    loop_connections
        .entry(accepted.query)
        .or_default()
        .insert(accepted.candidate);

    // 4. Essential graph; points follow their reference keyframes.
    let input = EssentialGraphInput {
        uncorrected,
        loop_connections,
        query: Some(accepted.query),
        fixed: Some(accepted.candidate),
        corrected_sim3: similarity.map(|_| corrected_sim3),
    };
    let outcome = optimise_essential_graph(map, &input)?;
    let before = &outcome.before;
    let mut moves: Vec<(MapPointId, Vector3<f64>)> = Vec::new();
    for point in map.map_points() {
        let r = point.reference_keyframe;
        let (Some(old), Ok(new)) = (before.get(&r), map.keyframe(r).map(|kf| kf.pose_cw())) else {
            continue;
        };
        // In the node's scale before, and back to the keyframe's after.
        let scale = outcome.scale_after.get(&r).copied().unwrap_or(1.0);
        let camera = old.transform_point(&point.position) / scale;
        moves.push((point.id(), new.inverse().transform_point(&camera)));
    }
    for (id, position) in moves {
        if let Ok(point) = map.map_point_mut(id) {
            point.position = position;
        }
    }
    for k in &moved {
        refresh_observed_points(map, *k);
    }

    // 5. The loop edge.
    map.add_loop_edge(accepted.query, accepted.candidate);
    Ok(LoopCorrection {
        correction_m,
        correction_deg,
        moved_keyframes: moved.len(),
        fused,
        graph_edges: outcome.edges,
        graph_iterations: outcome.summary.iterations,
        graph_ms: outcome.summary.total_seconds * 1e3,
    })
}
