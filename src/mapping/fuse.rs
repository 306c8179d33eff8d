//! Fusion of duplicated points: a keyframe's points projected into its
//! neighbours and theirs into it (ORB-SLAM3's `SearchInNeighbors` / `Fuse`).

use std::collections::BTreeSet;

use crate::camera::CameraRig;
use crate::error::{MapContext, SlamError};
use crate::map::{KeyFrameId, Map, MapPointId};
use crate::matching::KeypointGrid;
use crate::optim::LieGroup;

/// Search window at octave 0, pixels (ORB-SLAM3's `th = 3`).
const FUSE_RADIUS: f32 = 3.0;

/// Finds the keypoint of `target` that `point` projects onto, if any.
fn fuse_candidate(
    map: &Map,
    target: KeyFrameId,
    grid: &KeypointGrid,
    point: MapPointId,
    rig: &CameraRig,
) -> Option<usize> {
    let kf = map.keyframe(target).ok()?;
    let p = map.map_point(point).ok()?;
    let pc = kf.pose_cw().transform_point(&p.position);
    if pc.z <= 0.0 {
        return None;
    }
    let predicted = rig.camera.project_stereo(&pc);
    if !rig.contains(predicted.x, predicted.y) {
        return None;
    }
    let ray = p.position - kf.camera_center();
    let distance = ray.norm();
    if !p.in_distance_range(distance)
        || (p.normal.norm() > 0.0 && ray.dot(&p.normal) < 0.5 * distance)
    {
        return None;
    }
    let scales = &kf.measurements.scales;
    let scale_factor = f64::from(scales.scale_factors.get(1).copied().unwrap_or(1.2));
    let octave = p.predict_octave(distance, scale_factor, scales.n_levels());
    let radius = FUSE_RADIUS * scales.scale_factors.get(octave).copied().unwrap_or(1.0);
    let threshold = kf.measurements.distance_thresholds.low;
    let mut best: Option<(usize, f32)> = None;
    let octave = octave as i32;
    for i in grid.features_in_area(
        predicted.x as f32,
        predicted.y as f32,
        radius,
        Some((octave - 1, octave)),
    ) {
        let ok = kf
            .measurements
            .observation(i, rig.stereo_depth_limit())
            .is_some_and(|obs| obs.accepts_prediction(&predicted));
        if !ok {
            continue;
        }
        let Some(d) = kf
            .measurements
            .descriptors
            .row(i)
            .and_then(|r| p.descriptor.distance(&r))
        else {
            continue;
        };
        if d <= threshold && best.is_none_or(|(_, bd)| d < bd) {
            best = Some((i, d));
        }
    }
    best.map(|(i, _)| i)
}

/// A fusion found on a snapshot: `point` projects onto keypoint `index`
/// of `target`.
pub(crate) struct FusionCandidate {
    target: KeyFrameId,
    point: MapPointId,
    index: usize,
}

/// The candidates of `points` projected into `target` (read only).
fn candidates_in(
    map: &Map,
    target: KeyFrameId,
    points: &[MapPointId],
    rig: &CameraRig,
    out: &mut Vec<FusionCandidate>,
) {
    let Ok(kf) = map.keyframe(target) else {
        return;
    };
    let grid = KeypointGrid::new(&kf.measurements.keypoints, rig.width, rig.height);
    for &point in points {
        let already = map
            .map_point(point)
            .is_ok_and(|p| p.observations().contains_key(&target));
        if already {
            continue;
        }
        if let Some(index) = fuse_candidate(map, target, &grid, point, rig) {
            out.push(FusionCandidate {
                target,
                point,
                index,
            });
        }
    }
}

/// Compute: `keyframe`'s points projected into its neighbours (10 best
/// covisible and their 5 best), and theirs into it (read only).
pub(crate) fn plan_fusion(
    map: &Map,
    keyframe: KeyFrameId,
    rig: &CameraRig,
) -> Vec<FusionCandidate> {
    let mut targets: BTreeSet<KeyFrameId> = BTreeSet::new();
    // ORB-SLAM3's `SearchInNeighbors`: 10 neighbours, 30 for monocular.
    let neighbours = if rig.sensor == crate::camera::Sensor::Monocular {
        30
    } else {
        10
    };
    for n in map.best_covisible(keyframe, neighbours) {
        targets.insert(n);
        for m in map.best_covisible(n, 5) {
            targets.insert(m);
        }
    }
    targets.remove(&keyframe);
    let own: Vec<MapPointId> = map
        .keyframe(keyframe)
        .map(|k| k.observed_points().map(|(_, p)| p).collect())
        .unwrap_or_default();
    let mut planned = Vec::new();
    for target in &targets {
        candidates_in(map, *target, &own, rig, &mut planned);
    }
    let mut theirs: BTreeSet<MapPointId> = BTreeSet::new();
    for target in &targets {
        if let Ok(kf) = map.keyframe(*target) {
            theirs.extend(kf.observed_points().map(|(_, p)| p));
        }
    }
    let theirs: Vec<MapPointId> = theirs.into_iter().collect();
    candidates_in(map, keyframe, &theirs, rig, &mut planned);
    planned
}

/// Compute: `points` projected into each of `targets` (loop fusion,
/// ORB-SLAM3's `SearchAndFuse`; read only).
pub(crate) fn plan_fusion_into(
    map: &Map,
    targets: &[KeyFrameId],
    points: &[MapPointId],
    rig: &CameraRig,
) -> Vec<FusionCandidate> {
    let mut planned = Vec::new();
    for target in targets {
        candidates_in(map, *target, points, rig, &mut planned);
    }
    planned
}

/// Apply: a candidate landing on a keypoint with another point fuses the
/// two (the one with more observations survives, ORB-SLAM3's `Replace`),
/// one landing on a free keypoint gains the observation. Ids are resolved
/// again (earlier fusions, or local mapping's culling since the snapshot).
/// Then `keyframe`'s points and connections are refreshed. Returns how
/// many fusions and additions were made.
pub(crate) fn apply_fusion(
    map: &mut Map,
    keyframe: KeyFrameId,
    planned: Vec<FusionCandidate>,
) -> Result<usize, SlamError> {
    let changed = apply_fusion_candidates(map, planned)?;
    super::refresh_observed_points(map, keyframe);
    map.update_connections(keyframe);
    Ok(changed)
}

/// [`apply_fusion`] without the refresh of one keyframe (the caller
/// refreshes what it changed).
pub(crate) fn apply_fusion_candidates(
    map: &mut Map,
    planned: Vec<FusionCandidate>,
) -> Result<usize, SlamError> {
    let mut changed = 0;
    for c in planned {
        let Some(point) = map.resolve_point(c.point) else {
            continue;
        };
        let Ok(target) = map.keyframe(c.target) else {
            continue;
        };
        if c.index >= target.measurements.len()
            || map
                .map_point(point)
                .is_ok_and(|p| p.observations().contains_key(&c.target))
        {
            continue;
        }
        match target.map_point(c.index) {
            Some(other) if other != point => {
                let count = |id| map.map_point(id).map_or(0, |p| p.observation_count());
                if count(other) > count(point) {
                    map.replace_map_point(point, other).in_stage("fusion")?;
                } else {
                    map.replace_map_point(other, point).in_stage("fusion")?;
                }
                changed += 1;
            }
            Some(_) => {}
            None => {
                map.add_observation(point, c.target, c.index)
                    .in_stage("fusion")?;
                changed += 1;
            }
        }
    }
    Ok(changed)
}
