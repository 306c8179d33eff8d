//! Culling of weak map points and redundant keyframes (ORB-SLAM3's
//! `MapPointCulling` and `KeyFrameCulling`).

use super::ids::{KeyFrameId, MapPointId};
use super::Map;

/// Points found in fewer than this share of the frames predicting them are culled.
pub const MIN_FOUND_RATIO: f64 = 0.25;
/// A keyframe whose points are this redundant (seen by ≥ 3 others at the same
/// or a finer scale) is culled.
pub const REDUNDANT_FRACTION: f64 = 0.9;

/// What [`Map::cull_recent_points`] did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PointCullingReport {
    /// Points erased for a low found ratio.
    pub low_found_ratio: usize,
    /// Points erased for too few observations two keyframes after creation.
    pub too_few_observations: usize,
    /// Points that survived three keyframes and left the recent list.
    pub confirmed: usize,
}

impl Map {
    /// Checks recently created points against the current keyframe:
    /// - erased when found in fewer than 25% of the frames predicting them;
    /// - erased when, two keyframes after creation, they have at most
    ///   `min_observations` weighted observations (ORB-SLAM3: 2 mono, 3 stereo);
    /// - kept and dropped from `recent` after three keyframes.
    pub fn cull_recent_points(
        &mut self,
        recent: &mut Vec<MapPointId>,
        current: KeyFrameId,
        min_observations: usize,
    ) -> PointCullingReport {
        let mut report = PointCullingReport::default();
        let mut keep = Vec::with_capacity(recent.len());
        for &id in recent.iter() {
            let Some(p) = self.points.get(&id) else {
                continue;
            };
            let age = current.0.saturating_sub(p.first_keyframe.0);
            if p.found_ratio() < MIN_FOUND_RATIO {
                self.erase_map_point(id);
                report.low_found_ratio += 1;
            } else if age >= 2 && p.observation_count() <= min_observations {
                self.erase_map_point(id);
                report.too_few_observations += 1;
            } else if age >= 3 {
                report.confirmed += 1;
            } else {
                keep.push(id);
            }
        }
        *recent = keep;
        report
    }

    /// Among `candidates`, the keyframes whose points are at least 90%
    /// redundant: each seen by at least three other keyframes at the same or
    /// a finer octave (+1). With `close_depth`, only points with a stereo
    /// depth in (0, close_depth] count, as ORB-SLAM3 does for stereo. The
    /// map's first keyframe is never returned.
    pub fn redundant_keyframes(
        &self,
        candidates: &[KeyFrameId],
        close_depth: Option<f64>,
    ) -> Vec<KeyFrameId> {
        let first = self.keyframes.keys().next().copied();
        let mut redundant_keyframes = Vec::new();
        for &id in candidates {
            if Some(id) == first {
                continue;
            }
            let Some(kf) = self.keyframes.get(&id) else {
                continue;
            };
            let mut counted = 0usize;
            let mut redundant = 0usize;
            for (index, point) in kf.observed_points() {
                if let Some(limit) = close_depth {
                    match kf.measurements.stereo.get(index).copied().flatten() {
                        Some(s) if s.depth > 0.0 && f64::from(s.depth) <= limit => {}
                        _ => continue,
                    }
                }
                let Some(p) = self.points.get(&point) else {
                    continue;
                };
                counted += 1;
                if p.observations.len() <= 3 {
                    continue;
                }
                let octave = kf.measurements.keypoints.get(index).map_or(0, |k| k.octave);
                let finer = p
                    .observations
                    .iter()
                    .filter(|(other, _)| **other != id)
                    .filter(|(other, other_index)| {
                        self.keyframes
                            .get(other)
                            .and_then(|o| o.measurements.keypoints.get(**other_index))
                            .is_some_and(|k| k.octave <= octave + 1)
                    })
                    .count();
                if finer >= 3 {
                    redundant += 1;
                }
            }
            if counted > 0 && redundant as f64 > REDUNDANT_FRACTION * counted as f64 {
                redundant_keyframes.push(id);
            }
        }
        redundant_keyframes
    }
}
