//! Merge detection: the active map's keyframes against the older maps of
//! the atlas, as the merge branch of ORB-SLAM3's
//! `LoopClosing::NewDetectCommonRegions` (stereo and RGB-D: SE(3);
//! monocular: Sim(3), the new map's scale measured against the older
//! map's, as ORB-SLAM3's `Sim3Solver` does with `mbFixScale` false).
//!
//! Each older map keeps its keyframe database ([`MergeDetector::archive`]
//! when the system leaves it). A keyframe of the active map queries every
//! archived database (no covisibility to exclude: the maps share no
//! keyframe); the best candidates over all of them get the same
//! multi-stage check as a loop ([`verify_across`]), then the same
//! confirmation: the detecting keyframe and its covisible keyframes moved
//! by the correction must reach [`LoopThresholds::confirmations`], counting
//! the keyframes that verified the same map just before it (up to
//! [`LoopThresholds::max_misses`] may fail in between).
//!
//! A merge into the map the camera was lost from has one more stage: the
//! new map must land within reach of where that map lost the camera
//! ([`HandoverGap`], the [`Handover`] given by [`MergeDetector::start_map`]).
//!
//! Read only on the maps: the caller merges them (`Map::absorb`, then the
//! loop correction fuses the duplicates).

use std::collections::{BTreeMap, HashSet};
use std::ops::Deref;

use crate::camera::CameraRig;
use crate::error::{MapContext, SlamError};
use crate::map::{KeyFrameId, Map};
use crate::optim::{LieGroup, Sim3};
use crate::place::{KeyframeDatabase, QueryOptions};

use super::detector::AcceptedLoop;
use super::handover::{Handover, HandoverGap};
use super::stage_counts::CandidateCheck;
use super::streak::CandidateStreak;
use super::thresholds::LoopThresholds;
use super::verify::RejectedCandidate;
use super::verify::{check_candidate, detach_group, detach_query, CheckedCandidate};

/// A merge the detector accepted.
#[derive(Debug, Clone)]
pub struct AcceptedMerge {
    /// The older map's tag (its index in the caller's atlas).
    pub target: usize,
    /// `S_target,active`: takes the active map's world frame to the
    /// target's (`X_target = S · X_active = s·R·X_active + t`); its scale
    /// is 1 for stereo and RGB-D, the target's units per active unit for
    /// a monocular map.
    pub t_target_active: Sim3,
    /// The query keyframe (active map), the candidate (target map), the
    /// query's pose in the target's frame and its matches there.
    pub common: AcceptedLoop,
}

/// What one keyframe's merge check found.
#[derive(Debug, Clone, Default)]
pub struct MergeOutcome {
    /// The merge to carry out now, if any.
    pub accepted: Option<AcceptedMerge>,
    /// Candidates rejected after the descriptor stage, with their map's tag.
    pub rejected: Vec<(usize, RejectedCandidate)>,
    /// Every candidate checked, with its map's tag and what each stage
    /// counted.
    pub checks: Vec<(usize, CandidateCheck)>,
}

/// The archived databases and the confirmation streak.
pub struct MergeDetector {
    thresholds: LoopThresholds,
    archived: BTreeMap<usize, KeyframeDatabase<KeyFrameId>>,
    /// Verified keyframes of one target map (its atlas tag), waiting for
    /// enough of them.
    streak: Option<CandidateStreak<usize>>,
    /// Where the camera was lost when the active map was started, while
    /// that map is active.
    handover: Option<Handover>,
}

impl std::fmt::Debug for MergeDetector {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MergeDetector")
            .field("archived_maps", &self.archived.keys().collect::<Vec<_>>())
            .field("streak", &self.streak)
            .field("handover", &self.handover)
            .finish()
    }
}

impl MergeDetector {
    /// A detector with no archived map.
    pub fn new(thresholds: LoopThresholds) -> Self {
        Self {
            thresholds,
            archived: BTreeMap::new(),
            streak: None,
            handover: None,
        }
    }

    /// Keeps the database of a map the system left, under `tag`.
    pub fn archive(&mut self, tag: usize, database: KeyframeDatabase<KeyFrameId>) {
        if !database.is_empty() {
            self.archived.insert(tag, database);
        }
    }

    /// A new map became active: `handover` says where the camera was lost
    /// in the map given up (`None`: not known, e.g. a loaded atlas), until
    /// the next map starts or the active one is merged.
    pub fn start_map(&mut self, handover: Option<Handover>) {
        self.streak = None;
        self.handover = handover;
    }

    /// Takes an archived database back (its map became active again).
    pub fn take_archived(&mut self, tag: usize) -> Option<KeyframeDatabase<KeyFrameId>> {
        self.streak = None;
        self.handover = None;
        self.archived.remove(&tag)
    }

    /// Whether any older map can be merged with.
    pub fn has_archived(&self) -> bool {
        !self.archived.is_empty()
    }

    /// Forgets every archived map (a reset).
    pub fn clear(&mut self) {
        self.archived.clear();
        self.streak = None;
        self.handover = None;
    }

    /// Checks keyframe `kf` of the active map, with global descriptor
    /// `descriptor`, against the archived maps. The maps are read through
    /// `read_active` and `read_archived` (tag → map, `None`: skipped), once
    /// per step: each database query and each candidate's check takes its
    /// own short read locks, so that local mapping and tracking never wait
    /// for more than one step of the merge check.
    pub fn process<A, O>(
        &mut self,
        read_active: impl Fn() -> Result<A, SlamError>,
        kf: KeyFrameId,
        descriptor: &[f32],
        read_archived: impl Fn(usize) -> Option<Result<O, SlamError>>,
        rig: &CameraRig,
    ) -> Result<MergeOutcome, SlamError>
    where
        A: Deref<Target = Map>,
        O: Deref<Target = Map>,
    {
        let th = self.thresholds;
        let mut outcome = MergeOutcome::default();
        if read_active()?.keyframe_count() < th.min_keyframes {
            return Ok(outcome);
        }
        let mut candidates: Vec<(f32, usize, KeyFrameId)> = Vec::new();
        let options = QueryOptions {
            n_best: th.candidates,
            group_size: th.group_size,
            ..QueryOptions::default()
        };
        for (tag, database) in &self.archived {
            let Some(map) = read_archived(*tag).transpose()? else {
                continue;
            };
            let found = database
                .query(
                    descriptor,
                    &HashSet::new(),
                    |k| map.best_covisible(k, 10),
                    &options,
                )
                .in_stage("merge database query")?;
            candidates.extend(found.into_iter().map(|c| (c.score, *tag, c.keyframe)));
        }
        candidates.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        candidates.truncate(th.candidates);
        // The query's side is copied once and shared by the candidates.
        let mut query_side = None;
        for (score, tag, candidate) in candidates {
            let Some(map) = read_archived(tag).transpose()? else {
                continue;
            };
            // What the check reads is copied under short read locks (the
            // older map's, then the active map's); the check holds none. A
            // candidate culled since the query is rejected by the check.
            let (group, points) = detach_group(&map, candidate, &th);
            drop(map);
            let query_map = match query_side.take() {
                Some(copy) => copy,
                None => detach_query(&*read_active()?, kf, &th),
            };
            let mut checks = Vec::with_capacity(1);
            let checked = check_candidate(
                &query_map,
                kf,
                (&group, &points),
                score,
                rig,
                &th,
                &mut checks,
            )?;
            outcome.checks.extend(checks.into_iter().map(|c| (tag, c)));
            query_side = Some(query_map);
            let checked = match checked {
                Ok(checked) => checked,
                Err(record) => {
                    outcome.rejected.extend(record.map(|r| (tag, r)));
                    continue;
                }
            };
            // The query moves from T_qw to T_qw·C (in the target's units);
            // C takes target-world points to active-world ones.
            let CheckedCandidate {
                verified,
                correction,
                confirmations,
                ..
            } = checked;
            let t_target_active = correction.inverse();
            if let Some(handover) = self.handover.filter(|h| h.from_map == tag) {
                let gap = match read_archived(tag).transpose()? {
                    Some(target) => HandoverGap::measure(
                        &handover,
                        &target,
                        candidate,
                        &*read_active()?,
                        kf,
                        &t_target_active,
                    ),
                    None => None,
                };
                // This candidate's record (`check_candidate` just wrote it).
                let record = outcome
                    .checks
                    .iter_mut()
                    .rev()
                    .find(|(map, check)| *map == tag && check.candidate == candidate);
                if let Some((_, check)) = record {
                    check.counts.handover = gap;
                    if let Some((stage, count)) = check.counts.first_failing(&th) {
                        check.rejected_at = Some(stage);
                        outcome.rejected.push((
                            tag,
                            RejectedCandidate {
                                query: kf,
                                candidate,
                                score,
                                stage,
                                count,
                            },
                        ));
                        continue;
                    }
                }
            }
            let earlier = self
                .streak
                .as_ref()
                .filter(|s| s.subject == tag)
                .map_or(0, CandidateStreak::confirmations);
            let total = earlier + confirmations;
            tracing::debug!(
                keyframe = kf.0,
                target = tag,
                candidate = candidate.0,
                inliers = verified.inliers,
                confirmations,
                total,
                "merge verified"
            );
            if total < th.confirmations {
                self.streak = Some(CandidateStreak::start(tag, total));
                return Ok(outcome);
            }
            self.streak = None;
            outcome.accepted = Some(AcceptedMerge {
                target: tag,
                t_target_active,
                common: AcceptedLoop::from_verified(kf, verified, total),
            });
            return Ok(outcome);
        }
        if self.streak.as_mut().is_some_and(|s| s.miss(th.max_misses)) {
            self.streak = None;
        }
        Ok(outcome)
    }
}
