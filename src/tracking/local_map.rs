//! ORB-SLAM3's `TrackLocalMap`: the local keyframes and points, a search by
//! projection, and a pose refinement over every match.

use std::collections::{BTreeMap, BTreeSet};

use crate::map::{KeyFrameId, Map, MapPointId};

use super::frame::Frame;
use super::pose::refine_pose;
use super::search::{match_projected, visible_in_frame, VisiblePoint};
use crate::camera::CameraRig;
use crate::error::SlamError;

/// Local keyframes at most (ORB-SLAM3: 80).
const MAX_LOCAL_KEYFRAMES: usize = 80;

/// The local keyframes (those sharing points with the frame, then their
/// best covisible neighbours, children and parent) and the keyframe sharing
/// the most points, which becomes the frame's reference.
fn local_keyframes(frame: &Frame, map: &Map) -> (Vec<KeyFrameId>, Option<KeyFrameId>) {
    let mut counts: BTreeMap<KeyFrameId, usize> = BTreeMap::new();
    for point in frame.map_points.iter().flatten() {
        if let Ok(p) = map.map_point(*point) {
            for kf in p.observations().keys() {
                *counts.entry(*kf).or_default() += 1;
            }
        }
    }
    let reference = counts
        .iter()
        .max_by(|a, b| a.1.cmp(b.1).then(a.0.cmp(b.0)))
        .map(|(k, _)| *k);
    let mut direct: Vec<(KeyFrameId, usize)> = counts.into_iter().collect();
    direct.sort_by(|a, b| b.1.cmp(&a.1).then(b.0.cmp(&a.0)));
    direct.truncate(MAX_LOCAL_KEYFRAMES);
    let mut chosen: BTreeSet<KeyFrameId> = direct.iter().map(|(k, _)| *k).collect();
    let mut ordered: Vec<KeyFrameId> = direct.iter().map(|(k, _)| *k).collect();
    for (kf, _) in &direct {
        if ordered.len() >= MAX_LOCAL_KEYFRAMES {
            break;
        }
        let neighbours = map.best_covisible(*kf, 10);
        let family = map.children(*kf).into_iter().chain(map.parent(*kf));
        for n in neighbours.into_iter().chain(family) {
            if chosen.insert(n) {
                ordered.push(n);
                break;
            }
        }
    }
    (ordered, reference)
}

/// What local-map tracking found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct LocalMapOutcome {
    /// Inliers after the final refinement.
    pub inliers: usize,
    /// Local keyframes used.
    pub local_keyframes: usize,
    /// Local points predicted visible.
    pub visible_points: usize,
}

/// Whether local-map tracking counts the points it predicts visible and
/// finds (`visible`, `found`: local mapping's culling judges points by
/// them, ORB-SLAM3's `IncreaseVisible` / `IncreaseFound`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum PointCounting {
    /// A frame tracked live: its views count.
    Count,
    /// A frame localised after the fact: the map is only read.
    ReadOnly,
}

/// Tracks the local map. `recently_relocalised` widens the search as ORB-SLAM3 does.
pub(crate) fn track_local_map(
    frame: &mut Frame,
    map: &Map,
    rig: &CameraRig,
    recently_relocalised: bool,
    counting: PointCounting,
) -> Result<LocalMapOutcome, SlamError> {
    let count = counting == PointCounting::Count;
    let (keyframes, reference) = local_keyframes(frame, map);
    if let Some(reference) = reference {
        frame.reference_keyframe = Some(reference);
    }
    let matched: BTreeSet<MapPointId> = frame.map_points.iter().flatten().copied().collect();
    for id in matched.iter().filter(|_| count) {
        if let Ok(p) = map.map_point(*id) {
            p.visible.increment();
        }
    }
    let mut seen = matched.clone();
    let mut visible: Vec<VisiblePoint> = Vec::new();
    for kf in &keyframes {
        let Ok(kf) = map.keyframe(*kf) else { continue };
        for (_, point) in kf.observed_points() {
            if !seen.insert(point) {
                continue;
            }
            if let Some(v) = visible_in_frame(map, point, frame, rig) {
                visible.push(v);
            }
        }
    }
    for v in visible.iter().filter(|_| count) {
        if let Ok(p) = map.map_point(v.id) {
            p.visible.increment();
        }
    }
    let th = if recently_relocalised { 5.0 } else { 3.0 };
    let (frontal, oblique): (Vec<VisiblePoint>, Vec<VisiblePoint>) =
        visible.iter().partition(|v| v.frontal);
    match_projected(frame, map, &frontal, 2.5 * th, (1, 0), Some(0.8))?;
    match_projected(frame, map, &oblique, 4.0 * th, (1, 0), Some(0.8))?;
    let inliers = refine_pose(frame, map, rig)?;
    for id in frame.map_points.iter().flatten().filter(|_| count) {
        if let Ok(p) = map.map_point(*id) {
            p.found.increment();
        }
    }
    Ok(LocalMapOutcome {
        inliers,
        local_keyframes: keyframes.len(),
        visible_points: visible.len(),
    })
}
