//! What a run's records say, in the world frame: the anchored
//! trajectory (one pose per input frame, later maps anchored where the
//! previous one's motion carries the camera over the gap), the keyframes'
//! trajectory, and the totals.

use std::collections::BTreeMap;

use crate::error::SlamError;
use crate::loop_closing::{median_speed, Handover};
use crate::optim::{LieGroup, Se3};
use crate::tracking::{TrackingMethod, TrackingState};

use super::atlas::MapIndex;
use super::gap_motion::GapMotion;
use super::odometry_chain::linked;
use super::records::{FrameTimings, MapSummary, SlamSummary};
use super::second_look::SecondLookOutcome;
use super::SlamSystem;

/// One trajectory row: `(timestamp, T_wc, (map, anchor frame) for a
/// map's first pose)`.
type AnchoredRow = (f64, Se3, Option<(MapIndex, usize)>);

/// Tracked frames the camera's speed at a handover is taken over.
const HANDOVER_SPEED_FRAMES: usize = 10;

impl SlamSystem {
    /// Every processed frame's camera-to-world pose `T_wc`, one row per
    /// input frame, from its reference keyframe's current pose.
    ///
    /// A frame without a pose (before initialisation, lost, unreadable)
    /// gets the last tracked pose carried on at the last velocity for up
    /// to [`super::GAP_HORIZON_S`], turned by the rotation its images
    /// measured from the frame before where they did (identity before the
    /// first tracked frame; see [`super::gap_motion`]). The world is the first map's frame; a later
    /// map is anchored so that its first tracked frame sits where the last
    /// map's motion, carried over the gap the same way, puts it (see
    /// [`MapSummary::anchored_at_frame`]): the motion during the gap is
    /// not measured, and the map's drift from there on is its own.
    pub fn trajectory(&self) -> Result<Vec<(f64, Se3)>, SlamError> {
        Ok(self
            .anchored_poses()?
            .into_iter()
            .map(|(t, pose, _)| (t, pose))
            .collect())
    }

    /// The last processed frame's `T_wc` in the [trajectory](Self::trajectory)'s
    /// world frame; `None` when that frame was not tracked (or none was
    /// processed). Reads every record, like the trajectory.
    pub fn last_pose(&self) -> Result<Option<Se3>, SlamError> {
        let tracked = self
            .records
            .last()
            .is_some_and(|r| r.relative_pose.is_some());
        if !tracked {
            return Ok(None);
        }
        Ok(self.anchored_poses()?.last().map(|(_, pose, _)| *pose))
    }

    /// Where the camera was when map `map` was given up: its last tracked
    /// frame there (centre in that map's frame, reference keyframe) and
    /// its speed over its last [`HANDOVER_SPEED_FRAMES`] tracked frames
    /// there; `None` when no frame was tracked in it.
    pub(super) fn handover(&self, map: MapIndex) -> Result<Option<Handover>, SlamError> {
        let Some(entry) = self.atlas.get(map) else {
            return Err(SlamError::UnknownAtlasMap { map });
        };
        let read = entry.map.read().map_err(|_| SlamError::PoisonedMap)?;
        // (frame, centre, reference keyframe), newest first.
        let mut track = Vec::with_capacity(HANDOVER_SPEED_FRAMES);
        for record in self.records.iter().rev() {
            let Some(rel) = record.relative_pose.filter(|r| r.map == map) else {
                continue;
            };
            let Some(in_map) = rel.camera_in_map(&read) else {
                continue;
            };
            let centre = in_map.translation;
            track.push((record.index, centre, rel.keyframe));
            if track.len() == HANDOVER_SPEED_FRAMES {
                break;
            }
        }
        let Some(&(last_frame, last_centre, last_keyframe)) = track.first() else {
            return Ok(None);
        };
        let in_order: Vec<_> = track.iter().rev().map(|&(f, c, _)| (f, c)).collect();
        Ok(Some(Handover {
            from_map: map,
            last_frame,
            last_centre,
            last_keyframe,
            speed_m_per_frame: median_speed(&in_order),
        }))
    }

    /// `(timestamp, T_wc, (map, anchor frame) for a map's first pose)` per record.
    fn anchored_poses(&self) -> Result<Vec<AnchoredRow>, SlamError> {
        // Map → T_world,map.
        let mut anchors: BTreeMap<MapIndex, Se3> = BTreeMap::new();
        let mut motion = GapMotion::default();
        let mut previous_frame = None;
        let mut out = Vec::with_capacity(self.records.len());
        // Whether each row's pose came from its map.
        let mut from_map = Vec::with_capacity(self.records.len());
        for record in &self.records {
            let mut anchored = None;
            let mut pose = None;
            if let Some(rel) = record.relative_pose {
                let Some(entry) = self.atlas.get(rel.map) else {
                    return Err(SlamError::UnknownAtlasMap { map: rel.map });
                };
                let map = entry.map.read().map_err(|_| SlamError::PoisonedMap)?;
                if let Some(in_map) = rel.camera_in_map(&map) {
                    let loaded = entry.loaded;
                    let anchor = *anchors.entry(rel.map).or_insert_with(|| {
                        if loaded {
                            // A loaded map's frame is the world frame.
                            return Se3::identity();
                        }
                        if rel.map > 0 {
                            anchored = Some((rel.map, previous_frame.unwrap_or(record.index)));
                        }
                        motion
                            .next_gap_pose(
                                record.timestamp,
                                record.gap_step.as_ref(),
                                record.gap_rotation,
                            )
                            .compose(&in_map.inverse())
                    });
                    let world_pose = anchor.compose(&in_map);
                    motion.tracked(record.timestamp, world_pose);
                    previous_frame = Some(record.index);
                    pose = Some(world_pose);
                }
            }
            from_map.push(pose.is_some());
            let pose = pose.unwrap_or_else(|| {
                motion.next_gap_pose(
                    record.timestamp,
                    record.gap_step.as_ref(),
                    record.gap_rotation,
                )
            });
            out.push((record.timestamp, pose, anchored));
        }
        self.chain_odometry_backwards(&from_map, &mut out);
        Ok(out)
    }

    /// The frames posed by odometry (see [`super::odometry_chain`]) that
    /// are not joined forwards to a frame with a map pose hang from the
    /// next frame with one: each is placed by the step the frame after it
    /// measured, `T_w,c(k) = T_w,c(k+1) · T_c(k+1),c(k)`, from the newest
    /// back. (Those joined forwards were placed along their steps by the
    /// forward pass.)
    fn chain_odometry_backwards(&self, from_map: &[bool], out: &mut [AnchoredRow]) {
        let records = &self.records;
        let by_odometry = |k: usize| records[k].method == TrackingMethod::Odometry;
        let mut forwards = vec![false; records.len()];
        for k in 0..records.len() {
            forwards[k] = from_map.get(k).copied().unwrap_or(false)
                || (k > 0 && forwards[k - 1] && by_odometry(k) && linked(records, k - 1));
        }
        for k in (0..records.len().saturating_sub(1)).rev() {
            if !by_odometry(k) || forwards[k] || !linked(records, k) {
                continue;
            }
            let Some(step) = records[k + 1].gap_step else {
                continue;
            };
            out[k].1 = out[k + 1].1.compose(&step);
        }
    }

    /// The live keyframes' `(timestamp, T_wc)` of every map, in the
    /// trajectory's world frame, in creation order (map by map).
    pub fn keyframe_trajectory(&self) -> Result<Vec<(f64, Se3)>, SlamError> {
        let anchors = self.map_anchors()?;
        let mut out = Vec::new();
        for entry in self.atlas.maps() {
            let Some(anchor) = anchors.get(&entry.index) else {
                continue;
            };
            let map = entry.map.read().map_err(|_| SlamError::PoisonedMap)?;
            out.extend(
                map.keyframes()
                    .map(|kf| (kf.timestamp, anchor.compose(&kf.pose_wc()))),
            );
        }
        Ok(out)
    }

    /// `T_world,map` of every map with a tracked frame.
    pub(super) fn map_anchors(&self) -> Result<BTreeMap<MapIndex, Se3>, SlamError> {
        let poses = self.anchored_poses()?;
        let mut anchors = BTreeMap::new();
        for (record, (_, world_pose, _)) in self.records.iter().zip(&poses) {
            let Some(rel) = record.relative_pose else {
                continue;
            };
            if anchors.contains_key(&rel.map) {
                continue;
            }
            let Some(entry) = self.atlas.get(rel.map) else {
                continue;
            };
            let map = entry.map.read().map_err(|_| SlamError::PoisonedMap)?;
            if let Ok(kf_pose) = map.pose_cw_of(rel.keyframe) {
                let in_map = rel.pose.compose(&kf_pose).inverse();
                anchors.insert(rel.map, world_pose.compose(&in_map.inverse()));
            }
        }
        Ok(anchors)
    }

    /// Totals so far.
    pub fn summary(&self) -> Result<SlamSummary, SlamError> {
        let mut s = SlamSummary {
            frames: self.records.len(),
            second_look_levels: self.second_look_levels(),
            ..SlamSummary::default()
        };
        for entry in self.atlas.maps() {
            let map = entry.map.read().map_err(|_| SlamError::PoisonedMap)?;
            s.keyframes += map.keyframe_count();
            s.map_points += map.map_point_count();
            s.maps.push(MapSummary {
                index: entry.index,
                first_frame: entry.first_frame,
                keyframes: map.keyframe_count(),
                map_points: map.map_point_count(),
                merged_into: entry.merged_into,
                ..MapSummary::default()
            });
        }
        for (_, _, anchored) in self.anchored_poses()? {
            if let Some((map, frame)) = anchored {
                if let Some(m) = s.maps.get_mut(map) {
                    m.anchored_at_frame = Some(frame);
                }
            }
        }
        let mut sum = FrameTimings::default();
        for r in &self.records {
            match r.state {
                TrackingState::Ok => s.tracked += 1,
                TrackingState::Lost => s.lost += 1,
                TrackingState::NotInitialised => s.not_initialised += 1,
            }
            if let Some(m) = s.maps.get_mut(r.map) {
                m.frames += 1;
                m.tracked += usize::from(r.state == TrackingState::Ok);
            }
            s.unreadable += usize::from(r.unreadable.is_some());
            s.relocalisations += usize::from(r.method == TrackingMethod::Relocalisation);
            s.between_initial_views += usize::from(r.method == TrackingMethod::BetweenInitialViews);
            s.localised_after_loss += usize::from(r.method == TrackingMethod::AfterLoss);
            s.corroborated += usize::from(r.method == TrackingMethod::Corroborated);
            s.by_odometry += usize::from(r.method == TrackingMethod::Odometry);
            s.second_looks += usize::from(r.second_look.is_some());
            s.tracked_on_second_look +=
                usize::from(r.second_look == Some(SecondLookOutcome::Tracked));
            s.keyframes_inserted += usize::from(r.keyframe);
            sum.extraction_ms += r.timings.extraction_ms;
            sum.stereo_ms += r.timings.stereo_ms;
            sum.tracking_ms += r.timings.tracking_ms;
            sum.lock_wait_ms += r.timings.lock_wait_ms;
            sum.mapping_ms += r.timings.mapping_ms;
        }
        let n = self.records.len().max(1) as f64;
        s.mean_timings = FrameTimings {
            extraction_ms: sum.extraction_ms / n,
            stereo_ms: sum.stereo_ms / n,
            tracking_ms: sum.tracking_ms / n,
            lock_wait_ms: sum.lock_wait_ms / n,
            mapping_ms: sum.mapping_ms / n,
        };
        Ok(s)
    }
}
