//! The global bundle adjustment after a loop correction, as ORB-SLAM3's
//! `LoopClosing::RunGlobalBundleAdjustment`: every live keyframe (the
//! map's first one fixed) and every point, 10 Levenberg–Marquardt
//! iterations with the Huber kernel, on a detached snapshot, so it can run
//! on a background thread while tracking and local mapping go on, and be
//! aborted when a new loop arrives.
//!
//! Snapshot → solve → apply:
//! - [`snapshot_global_ba`] copies the problem (read lock);
//! - [`solve_global_ba`] optimises it (no lock; abortable);
//! - [`apply_global_ba`] writes it back (write lock, local mapping paused).
//!   Keyframes made after the snapshot follow their spanning-tree parent's
//!   correction (`T_c ← T_c·T_p⁻¹·T_p'`), points not in the snapshot their
//!   reference keyframe's, as ORB-SLAM3 propagates them.

use std::collections::{BTreeMap, VecDeque};
use std::sync::atomic::AtomicBool;

use crate::camera::CameraRig;
use crate::error::{MapContext, SlamError};
use crate::map::{KeyFrameId, Map, MapPointId};
use crate::mapping::build_map_bundle;
use crate::optim::local_ba::{
    local_bundle_adjustment_abortable, BundleProblem, LocalBaConfig, Termination,
};
use crate::optim::{LieGroup, Se3};

/// LM iterations (ORB-SLAM3: `GlobalBundleAdjustemnt(pMap, 10, …)`).
pub const GLOBAL_BA_ITERATIONS: usize = 10;

/// What a global BA did.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct GlobalBaSummary {
    /// Keyframes in the snapshot.
    pub keyframes: usize,
    /// Points in the snapshot.
    pub points: usize,
    /// Observations in the snapshot.
    pub observations: usize,
    /// Keyframes made after the snapshot, moved with their parents.
    pub propagated_keyframes: usize,
    /// Whether it was aborted (then nothing was applied).
    pub aborted: bool,
    /// Time of the solve (ms).
    pub solve_ms: f64,
    /// Why it failed (an error, or its thread's panic), when it did: then
    /// nothing was applied and the run went on without it.
    pub failure: Option<String>,
}

/// The detached problem with the ids to write it back.
#[derive(Debug)]
pub struct GlobalBaSnapshot {
    problem: BundleProblem,
    keyframes: Vec<KeyFrameId>,
    points: Vec<MapPointId>,
}

/// A solved global BA, ready to apply.
#[derive(Debug)]
pub struct SolvedGlobalBa {
    snapshot: GlobalBaSnapshot,
    summary: GlobalBaSummary,
}

impl SolvedGlobalBa {
    /// What the solve did.
    pub fn summary(&self) -> GlobalBaSummary {
        self.summary.clone()
    }
}

/// Snapshot: the whole map as a BA problem (read only). `None` when the
/// map has fewer than two keyframes or no observation.
pub fn snapshot_global_ba(map: &Map, rig: &CameraRig) -> Option<GlobalBaSnapshot> {
    if map.keyframe_count() < 2 {
        return None;
    }
    let keyframes = map.keyframes().enumerate().map(|(i, k)| (k.id(), i == 0));
    let points: Vec<MapPointId> = map.map_points().map(|p| p.id()).collect();
    let bundle = build_map_bundle(map, rig, keyframes, points)?;
    Some(GlobalBaSnapshot {
        problem: bundle.problem,
        keyframes: bundle.keyframes,
        points: bundle.points,
    })
}

/// Solve: 10 robust LM iterations (no second stage, as ORB-SLAM3's global
/// BA), stopping after the current iteration when `abort` is raised.
pub fn solve_global_ba(
    mut snapshot: GlobalBaSnapshot,
    abort: &AtomicBool,
) -> Result<SolvedGlobalBa, SlamError> {
    let start = std::time::Instant::now();
    let config = LocalBaConfig {
        first_stage_iterations: GLOBAL_BA_ITERATIONS,
        second_stage_iterations: 0,
        ..LocalBaConfig::default()
    };
    let report = local_bundle_adjustment_abortable(&mut snapshot.problem, &config, Some(abort))
        .in_stage("global bundle adjustment")?;
    let summary = GlobalBaSummary {
        keyframes: snapshot.keyframes.len(),
        points: snapshot.points.len(),
        observations: snapshot.problem.observations.len(),
        propagated_keyframes: 0,
        aborted: report.first_stage.termination == Termination::Aborted,
        solve_ms: start.elapsed().as_secs_f64() * 1e3,
        failure: None,
    };
    Ok(SolvedGlobalBa { snapshot, summary })
}

/// Apply: writes the solution and propagates it to what was made since
/// (see the module's docs). An aborted solve changes nothing.
pub fn apply_global_ba(map: &mut Map, solved: SolvedGlobalBa) -> GlobalBaSummary {
    let SolvedGlobalBa {
        snapshot,
        mut summary,
    } = solved;
    if summary.aborted {
        return summary;
    }
    // Old and new poses of every keyframe the solution reaches.
    let mut corrected: BTreeMap<KeyFrameId, (Se3, Se3)> = BTreeMap::new();
    for (kf, pose) in snapshot.keyframes.iter().zip(&snapshot.problem.poses) {
        if let Ok(k) = map.keyframe(*kf) {
            corrected.insert(*kf, (k.pose_cw(), *pose));
        }
    }
    // Keyframes made since: breadth first down the spanning tree.
    let mut queue: VecDeque<KeyFrameId> = corrected.keys().copied().collect();
    while let Some(parent) = queue.pop_front() {
        let Some(&(parent_old, parent_new)) = corrected.get(&parent) else {
            continue;
        };
        for child in map.children(parent) {
            if corrected.contains_key(&child) {
                continue;
            }
            if let Ok(k) = map.keyframe(child) {
                let old = k.pose_cw();
                let new = old.compose(&parent_old.inverse()).compose(&parent_new);
                corrected.insert(child, (old, new));
                summary.propagated_keyframes += 1;
                queue.push_back(child);
            }
        }
    }
    for (kf, (_, new)) in &corrected {
        if let Ok(k) = map.keyframe_mut(*kf) {
            k.set_pose_cw(*new);
        }
    }
    let solved_points: BTreeMap<MapPointId, usize> = snapshot
        .points
        .iter()
        .enumerate()
        .map(|(i, p)| (*p, i))
        .collect();
    let mut moves = Vec::new();
    for point in map.map_points() {
        let position = match solved_points.get(&point.id()) {
            Some(&i) => snapshot.problem.points[i],
            None => {
                let Some((old, new)) = corrected.get(&point.reference_keyframe) else {
                    continue;
                };
                new.inverse()
                    .transform_point(&old.transform_point(&point.position))
            }
        };
        moves.push((point.id(), position));
    }
    for (id, position) in moves {
        if let Ok(p) = map.map_point_mut(id) {
            p.position = position;
        }
        map.update_normal_and_depth(id);
    }
    summary
}
