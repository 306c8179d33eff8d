//! Local bundle adjustment over a keyframe and its covisible neighbours,
//! with the other keyframes observing the points held fixed.

use std::collections::{BTreeMap, BTreeSet};

use crate::map::{KeyFrameId, Map, MapPointId};
use crate::optim::local_ba::{
    local_bundle_adjustment, BaObservation, BundleProblem, LocalBaConfig,
};
use crate::optim::reprojection::Observation;
use crate::tracking::{MapContext, SlamError, StereoRig};

/// Local keyframes at most (beyond the new one).
const MAX_LOCAL_KEYFRAMES: usize = 20;
/// Fixed keyframes at most.
const MAX_FIXED_KEYFRAMES: usize = 20;

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
}

fn keyframe_observation(map: &Map, kf: KeyFrameId, index: usize) -> Option<Observation> {
    let kf = map.keyframe(kf).ok()?;
    let m = &kf.measurements;
    let kp = m.keypoints.get(index)?;
    let information = f64::from(
        *m.scales
            .inv_level_sigma2
            .get(usize::try_from(kp.octave).ok()?)?,
    );
    let (u, v) = (f64::from(kp.x), f64::from(kp.y));
    Some(match m.stereo.get(index).copied().flatten() {
        Some(s) if s.depth > 0.0 => Observation::stereo(u, v, f64::from(s.right_u), information),
        _ => Observation::mono(u, v, information),
    })
}

/// Runs local BA around `keyframe` and writes the result into the map.
pub fn local_bundle_adjustment_around(
    map: &mut Map,
    keyframe: KeyFrameId,
    rig: &StereoRig,
) -> Result<BundleSummary, SlamError> {
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
    let mut pose_index: BTreeMap<KeyFrameId, usize> = BTreeMap::new();
    let mut poses = Vec::new();
    let mut fixed = Vec::new();
    for kf in local.iter().chain(fixed_set.iter()) {
        let Ok(k) = map.keyframe(*kf) else { continue };
        pose_index.insert(*kf, poses.len());
        poses.push(k.pose_cw());
        fixed.push(!local_set.contains(kf) || Some(*kf) == first);
    }
    if fixed.iter().all(|f| !f) {
        // No gauge from the map: hold the oldest local keyframe.
        if let Some(oldest) = local.iter().min().and_then(|k| pose_index.get(k)) {
            fixed[*oldest] = true;
        }
    }
    let mut observations = Vec::new();
    let mut links = Vec::new();
    let mut positions = Vec::with_capacity(points.len());
    for (pi, p) in points.iter().enumerate() {
        let Ok(point) = map.map_point(*p) else {
            continue;
        };
        positions.push(point.position);
        for (kf, index) in point.observations() {
            let (Some(&pose), Some(obs)) =
                (pose_index.get(kf), keyframe_observation(map, *kf, *index))
            else {
                continue;
            };
            observations.push(BaObservation {
                pose,
                point: pi,
                obs,
            });
            links.push((*p, *kf));
        }
    }
    if observations.is_empty() || positions.len() != points.len() {
        return Ok(BundleSummary::default());
    }
    let mut problem = BundleProblem {
        camera: rig.camera,
        poses,
        fixed,
        points: positions,
        observations,
    };
    let report = local_bundle_adjustment(&mut problem, &LocalBaConfig::default())
        .in_stage("local bundle adjustment")?;
    for (kf, &i) in &pose_index {
        if !problem.fixed[i] {
            if let Ok(k) = map.keyframe_mut(*kf) {
                k.set_pose_cw(problem.poses[i]);
            }
        }
    }
    for (p, position) in points.iter().zip(&problem.points) {
        if let Ok(point) = map.map_point_mut(*p) {
            point.position = *position;
        }
    }
    let mut erased = 0;
    for &o in &report.outliers {
        if let Some(&(p, kf)) = links.get(o) {
            if map.map_point(p).is_ok() {
                map.erase_observation(p, kf).in_stage("BA outliers")?;
                erased += 1;
            }
        }
    }
    for p in &points {
        map.update_normal_and_depth(*p);
    }
    Ok(BundleSummary {
        local_keyframes: local_set.len(),
        fixed_keyframes: fixed_set.len(),
        points: points.len(),
        outliers_erased: erased,
    })
}
