//! Local bundle adjustment over a keyframe and its most covisible
//! neighbours, with other keyframes observing their points held fixed
//! (the window: [`snapshot_bundle`]), in three steps: snapshot (read
//! lock), solve (no lock), apply (write lock).

use std::collections::{BTreeMap, BTreeSet};
use std::sync::atomic::AtomicBool;

use crate::camera::CameraRig;
use crate::error::{MapContext, SlamError};
use crate::map::{KeyFrameId, Map, MapPointId};
use crate::optim::local_ba::{
    local_bundle_adjustment_abortable, BundleProblem, LocalBaConfig, Termination,
};

use super::bundle_problem::build_map_bundle;

/// Covisible keyframes optimised at most (beyond the new one), the most
/// covisible first.
pub const MAX_LOCAL_KEYFRAMES: usize = 20;
/// Fixed keyframes at most (see `snapshot_bundle`'s window).
pub const MAX_FIXED_KEYFRAMES: usize = 20;

/// What one local BA did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct BundleSummary {
    /// Keyframes optimised.
    pub local_keyframes: usize,
    /// Keyframes held fixed.
    pub fixed_keyframes: usize,
    /// Points optimised.
    pub points: usize,
    /// Observations erased as outliers.
    pub outliers_erased: usize,
    /// Whether it was aborted early (monocular tracking wanted a keyframe
    /// while mapping was busy, or the mapping thread was stopped).
    pub aborted: bool,
}

/// A local BA problem built from a map snapshot, with the ids needed to
/// write its solution back.
pub(crate) struct BundleSnapshot {
    problem: BundleProblem,
    /// Keyframe → pose index in the problem.
    pose_index: BTreeMap<KeyFrameId, usize>,
    /// Point index in the problem → map point.
    points: Vec<MapPointId>,
    /// Observation index in the problem → (point, keyframe).
    links: Vec<(MapPointId, KeyFrameId)>,
    local_keyframes: usize,
    fixed_keyframes: usize,
}

/// Snapshot: builds the local BA problem around `keyframe` (read only;
/// the problem is a detached copy). `None` when there is nothing to optimise.
///
/// The window differs from ORB-SLAM3's `Optimizer::LocalBundleAdjustment`
/// (every covisible keyframe optimised, every other observer of their
/// points fixed), for a measured reason (`EVALUATION.md`, "Local BA
/// window"): the new keyframe and its [`MAX_LOCAL_KEYFRAMES`] most
/// covisible keyframes are optimised (the map's first keyframe excepted),
/// and the first [`MAX_FIXED_KEYFRAMES`] other observers met walking the
/// local points (in practice the oldest) are held fixed. On the synthetic
/// highway, ORB-SLAM3's full window drifted 1.07 % (SuperPoint) and 0.53 %
/// (ORB) against 0.59 % and 0.22 % with this one, and KITTI 06 with
/// SuperPoint ended at 0.083 m against 0.078 m; fixing the 20 observers
/// that see the most local points instead (a cap by weight) was in
/// between (0.74 %, 0.51 %, 0.088 m).
pub(crate) fn snapshot_bundle(
    map: &Map,
    keyframe: KeyFrameId,
    rig: &CameraRig,
) -> Option<BundleSnapshot> {
    let first = map.keyframes().next().map(|k| k.id());
    let mut local = vec![keyframe];
    local.extend(map.best_covisible(keyframe, MAX_LOCAL_KEYFRAMES));
    let local_set: BTreeSet<KeyFrameId> = local.iter().copied().collect();
    let mut points: Vec<MapPointId> = Vec::new();
    let mut seen = BTreeSet::new();
    for kf in &local {
        let Ok(kf) = map.keyframe(*kf) else { continue };
        for (_, p) in kf.observed_points() {
            if seen.insert(p) {
                points.push(p);
            }
        }
    }
    // The other observers of the local points, the oldest first (ascending
    // id), at most MAX_FIXED_KEYFRAMES: see the window's docs above.
    let mut fixed_set: BTreeSet<KeyFrameId> = BTreeSet::new();
    for p in &points {
        let Ok(point) = map.map_point(*p) else {
            continue;
        };
        for kf in point.observations().keys() {
            if !local_set.contains(kf) && fixed_set.len() < MAX_FIXED_KEYFRAMES {
                fixed_set.insert(*kf);
            }
        }
    }
    // The new keyframe and its covisible ones are free (the map's first
    // keyframe excepted); the other observers of their points are fixed.
    let mut chosen: Vec<(KeyFrameId, bool)> = local
        .iter()
        .map(|kf| (*kf, Some(*kf) == first))
        .chain(fixed_set.iter().map(|kf| (*kf, true)))
        .filter(|(kf, _)| map.keyframe(*kf).is_ok())
        .collect();
    if chosen.iter().all(|(_, f)| !f) {
        // No gauge from the map: hold the oldest local keyframe.
        if let Some(oldest) = chosen.iter_mut().min_by_key(|(kf, _)| *kf) {
            oldest.1 = true;
        }
    }
    let bundle = build_map_bundle(map, rig, chosen, points)?;
    Some(BundleSnapshot {
        problem: bundle.problem,
        pose_index: bundle.pose_index,
        points: bundle.points,
        links: bundle.links,
        local_keyframes: local_set.len(),
        fixed_keyframes: fixed_set.len(),
    })
}

/// A solved local BA, ready to be applied.
pub(crate) struct SolvedBundle {
    snapshot: BundleSnapshot,
    outliers: Vec<usize>,
    /// Whether the abort flag cut the solve short.
    pub aborted: bool,
}

/// Solve: runs the optimiser on the detached problem (no lock needed),
/// stopping after the current iteration when `abort` is raised, and after
/// `iteration_share` of its iterations (1: all; less where a slow
/// machine's BA was interrupted, see [`super::LocalMapper::set_bundle_share`]).
pub(crate) fn solve_bundle(
    mut snapshot: BundleSnapshot,
    abort: &AtomicBool,
    iteration_share: f64,
) -> Result<SolvedBundle, SlamError> {
    let config = LocalBaConfig::default().with_iteration_share(iteration_share);
    let report = local_bundle_adjustment_abortable(&mut snapshot.problem, &config, Some(abort))
        .in_stage("local bundle adjustment")?;
    // A cut iteration budget that the solve used up counts as an abort.
    let stopped_by_budget = |t: Termination| {
        iteration_share < 1.0 && matches!(t, Termination::IterationLimit | Termination::Skipped)
    };
    let aborted = [report.first_stage, report.second_stage]
        .iter()
        .any(|s| s.termination == Termination::Aborted || stopped_by_budget(s.termination));
    Ok(SolvedBundle {
        snapshot,
        outliers: report.outliers,
        aborted,
    })
}

/// Apply: writes the solution into the map. Keyframes and points culled or
/// fused since the snapshot are skipped; outlier observations are erased
/// only where they still exist.
pub(crate) fn apply_bundle(
    map: &mut Map,
    solved: SolvedBundle,
) -> Result<BundleSummary, SlamError> {
    let SolvedBundle {
        snapshot,
        outliers,
        aborted,
    } = solved;
    let problem = &snapshot.problem;
    for (kf, &i) in &snapshot.pose_index {
        if !problem.fixed[i] {
            if let Ok(k) = map.keyframe_mut(*kf) {
                k.set_pose_cw(problem.poses[i]);
            }
        }
    }
    for (p, position) in snapshot.points.iter().zip(&problem.points) {
        if let Ok(point) = map.map_point_mut(*p) {
            point.position = *position;
        }
    }
    let mut erased = 0;
    for &o in &outliers {
        if let Some(&(p, kf)) = snapshot.links.get(o) {
            if map
                .map_point(p)
                .is_ok_and(|point| point.observations().contains_key(&kf))
            {
                map.erase_observation(p, kf).in_stage("BA outliers")?;
                erased += 1;
            }
        }
    }
    for p in &snapshot.points {
        map.update_normal_and_depth(*p);
    }
    Ok(BundleSummary {
        local_keyframes: snapshot.local_keyframes,
        fixed_keyframes: snapshot.fixed_keyframes,
        points: snapshot.points.len(),
        outliers_erased: erased,
        aborted,
    })
}
