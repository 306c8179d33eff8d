//! Whether a merge can put the new map where it does: the last stage of a
//! merge check into the map the camera was lost from.
//!
//! When tracking stays lost the system starts a new map (ORB-SLAM3's
//! `Atlas::CreateNewMap`); the camera went on from where the old map last
//! tracked it. A merge of the new map into that map registers the new
//! map's first keyframe somewhere in the old one. A true revisit puts it
//! within what the camera can have travelled while lost, plus what both
//! maps can have drifted since; repeated texture can register a keyframe
//! against the same pattern anywhere, with as many inliers as a true
//! revisit (the repeated-texture RGB-D lap with the phase-excess rejection
//! merged a map into a place 70 m from the truth with 146 inliers and
//! three confirmations: EVALUATION.md, "Phase-excess rejection on dim
//! laps"). This stage stops such a merge when it goes back into the map
//! just left, as the drift stage ([`super::LoopDrift`]) stops a
//! look-alike loop. ORB-SLAM3 does not
//! gate visual merges (`LoopClosing::NewDetectCommonRegions` accepts any
//! merge its geometric checks confirm).
//!
//! Only the map the camera was lost from is judged: the handover says
//! nothing about where an older map lies. A camera carried elsewhere while
//! lost (a kidnap) is not merged into the map it left: two maps stay, none
//! of their work lost, where a wrong merge would corrupt both.

use nalgebra::Vector3;

use crate::map::{KeyFrameId, Map};
use crate::optim::{LieGroup, Sim3};

use super::drift::travel_between;
use super::thresholds::LoopThresholds;

/// Where and how fast the camera was when the system gave a map up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Handover {
    /// The map given up (its atlas tag).
    pub from_map: usize,
    /// The last input frame tracked in it.
    pub last_frame: usize,
    /// That frame's camera centre in the map's world frame (metres).
    pub last_centre: Vector3<f64>,
    /// That frame's reference keyframe: the old map's drift is counted
    /// from a merge candidate to it.
    pub last_keyframe: KeyFrameId,
    /// The camera's speed over its last tracked frames there (metres per
    /// frame; see [`median_speed`]).
    pub speed_m_per_frame: f64,
}

/// A merge's placement of the new map next to the handover: what the
/// stage judges ([`HandoverGap::excess`]).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HandoverGap {
    /// Distance from the old map's last tracked camera centre to the new
    /// map's first keyframe as the merge places it (metres).
    pub gap_m: f64,
    /// Input frames between the two.
    pub frames: usize,
    /// The speed allowed for: the larger of the camera's speed before the
    /// loss and its mean speed in the new map (metres per frame).
    pub speed_m_per_frame: f64,
    /// The way along which drift may have built up: in the old map from
    /// the merge candidate to the last tracked keyframe, and in the new
    /// map from its first keyframe to the query (metres).
    pub drift_path_m: f64,
    /// The query keyframe's median scene depth (metres; 0 without points).
    pub scene_depth_m: f64,
}

impl HandoverGap {
    /// The largest gap a true revisit explains under `th`: the way the
    /// camera covers in `frames` at [`LoopThresholds::max_handover_speedup`]
    /// times the speed, plus the drift the loop's drift stage allows on
    /// the drift path ([`LoopThresholds::max_drift_ratio`]) and its floor
    /// ([`LoopThresholds::drift_floor_depths`] of the scene's depth).
    pub fn allowed_m(&self, th: &LoopThresholds) -> f64 {
        th.max_handover_speedup * self.speed_m_per_frame * self.frames as f64
            + th.max_drift_ratio * self.drift_path_m
            + th.drift_floor_depths * self.scene_depth_m
    }

    /// How many times over what a true revisit explains the gap is: above
    /// 1, the merge is not one.
    pub fn excess(&self, th: &LoopThresholds) -> f64 {
        let allowed = self.allowed_m(th);
        if allowed > 0.0 {
            self.gap_m / allowed
        } else if self.gap_m > 0.0 {
            f64::INFINITY
        } else {
            0.0
        }
    }

    /// Measures the merge `t_target_active` (`X_target = S · X_active`)
    /// of the map started after `handover` (`active`, queried by keyframe
    /// `query`) into the map it left (`target`, matched at `candidate`).
    /// Lengths are in the target's units (a monocular new map's are
    /// scaled by `S`'s scale).
    /// The new map's first keyframe is its earliest live keyframe after
    /// the handover's frame; `None` when it has none.
    pub fn measure(
        handover: &Handover,
        target: &Map,
        candidate: KeyFrameId,
        active: &Map,
        query: KeyFrameId,
        t_target_active: &Sim3,
    ) -> Option<Self> {
        let scale = t_target_active.scale;
        let first = active
            .keyframes()
            .filter(|k| k.frame_index > handover.last_frame)
            .min_by_key(|k| (k.frame_index, k.id()))?;
        let placed = t_target_active.transform_point(&first.pose_wc().translation);
        let gap_m = (placed - handover.last_centre).norm();
        let frames = first.frame_index.saturating_sub(handover.last_frame).max(1);
        let new_path_m =
            scale * travel_between(active, first.id(), query).map_or(0.0, |t| t.path_m);
        let query_frame = active
            .keyframe(query)
            .map_or(first.frame_index, |k| k.frame_index);
        let new_speed = new_path_m / query_frame.saturating_sub(first.frame_index).max(1) as f64;
        // The keyframe the old map last tracked from, or its newest if
        // that one was culled since.
        let last_keyframe = if target.keyframe(handover.last_keyframe).is_ok() {
            Some(handover.last_keyframe)
        } else {
            target.keyframes().map(|k| k.id()).max()
        };
        let old_path_m = last_keyframe
            .and_then(|last| travel_between(target, candidate, last))
            .map_or(0.0, |t| t.path_m);
        Some(Self {
            gap_m,
            frames,
            speed_m_per_frame: handover.speed_m_per_frame.max(new_speed),
            drift_path_m: old_path_m + new_path_m,
            scene_depth_m: scale * active.median_scene_depth(query).unwrap_or(0.0),
        })
    }
}

/// The camera's speed from its last tracked frames, `(input frame, camera
/// centre)` in frame order: the median of the steps between consecutive
/// ones, each divided by the frames it spans (0 with fewer than two).
pub fn median_speed(track: &[(usize, Vector3<f64>)]) -> f64 {
    let mut steps: Vec<f64> = track
        .windows(2)
        .filter(|w| w[1].0 > w[0].0)
        .map(|w| (w[1].1 - w[0].1).norm() / (w[1].0 - w[0].0) as f64)
        .collect();
    crate::stats::upper_median(&mut steps).unwrap_or(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gap(gap_m: f64, frames: usize, speed: f64, drift_path_m: f64, depth: f64) -> HandoverGap {
        HandoverGap {
            gap_m,
            frames,
            speed_m_per_frame: speed,
            drift_path_m,
            scene_depth_m: depth,
        }
    }

    #[test]
    fn the_way_covered_while_lost_and_the_drift_are_allowed_and_no_more() {
        let th = LoopThresholds::default();
        let s = th.max_handover_speedup;
        // 25 frames lost at 1 m per frame, 200 m of drift path, 5 m deep.
        let allowed = s * 25.0 + th.max_drift_ratio * 200.0 + th.drift_floor_depths * 5.0;
        let at = |gap_m| gap(gap_m, 25, 1.0, 200.0, 5.0);
        assert!((at(1.0).allowed_m(&th) - allowed).abs() < 1e-12);
        assert!(at(0.999 * allowed).excess(&th) < 1.0);
        assert!(at(1.001 * allowed).excess(&th) > 1.0);
        // A standing camera with no path: only the depth floor.
        assert!(gap(0.4, 3, 0.0, 0.0, 5.0).excess(&th) < 1.0);
        assert!(gap(0.6, 3, 0.0, 0.0, 5.0).excess(&th) > 1.0);
        // Nothing allowed: any gap is infinitely too far, none is fine.
        assert_eq!(gap(0.1, 3, 0.0, 0.0, 0.0).excess(&th), f64::INFINITY);
        assert_eq!(gap(0.0, 3, 0.0, 0.0, 0.0).excess(&th), 0.0);
    }

    #[test]
    fn the_false_merge_of_the_repeated_texture_lap_is_too_far() {
        // The numbers of EVALUATION.md's false merge: a map started after
        // a few lost frames at about 1 m per frame, placed 70 m from where
        // the camera was lost.
        let th = LoopThresholds::default();
        assert!(gap(70.0, 5, 1.0, 16.0 + 98.0, 5.0).excess(&th) > 2.0);
    }

    #[test]
    fn median_speed_is_robust_to_one_jump_and_spans_skipped_frames() {
        let at = |x: f64| Vector3::new(x, 0.0, 0.0);
        let track = [
            (10, at(0.0)),
            (11, at(1.0)),
            (13, at(3.0)),
            (14, at(40.0)),
            (15, at(41.0)),
        ];
        assert!((median_speed(&track) - 1.0).abs() < 1e-12);
        assert_eq!(median_speed(&track[..1]), 0.0);
        assert_eq!(median_speed(&[]), 0.0);
    }
}
