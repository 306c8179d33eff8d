//! The loop-closing stage of the system: every keyframe local mapping has
//! processed is checked for a loop ([`LoopDetector`]) and, when the atlas
//! holds older maps, for a merge with one of them ([`MergeDetector`]); an
//! accepted loop is corrected on the map ([`correct_loop`]), an accepted
//! merge absorbs the active map into the older one (`Map::absorb`, then
//! the same correction fuses the duplicates), while local mapping is
//! paused; both are recorded. The records name input frames, not keyframe
//! ids.

use std::collections::VecDeque;
use std::sync::Arc;

use serde::Serialize;

use crate::camera::CameraRig;
use crate::error::SlamError;
use std::collections::BTreeMap;

use crate::error::MapContext;
use crate::loop_closing::{
    correct_loop, pose_difference, AcceptedLoop, AcceptedMerge, CandidateCheck, Handover,
    LoopCorrection, LoopDetector, LoopStage, LoopStageCounts, LoopThresholds, MergeDetector,
    SharedKeyframeDatabase,
};
use crate::map::{KeyFrameId, Map, SharedMap};
use crate::optim::{LieGroup, Se3};
use crate::place::GlobalDescriptor;

/// An accepted, corrected loop.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LoopRecord {
    /// Input frame of the keyframe that closed it.
    pub query_frame: usize,
    /// Input frame of the loop keyframe it matched.
    pub match_frame: usize,
    /// Inliers of the last pose optimisation.
    pub inliers: usize,
    /// How far the query keyframe moved (metres).
    pub correction_m: f64,
    /// How far it turned (degrees).
    pub correction_deg: f64,
    /// Keyframes that agreed, the detecting one included.
    pub confirmations: usize,
    /// The correction's details.
    pub correction: LoopCorrection,
}

/// An accepted merge of the active map into an older map of the atlas.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MergeRecord {
    /// Input frame of the keyframe that detected it (in the merged map).
    pub query_frame: usize,
    /// Input frame of the older map's keyframe it matched.
    pub match_frame: usize,
    /// The atlas map absorbed (the active one until then).
    pub merged_map: usize,
    /// The atlas map it was absorbed into (active from then on).
    pub into_map: usize,
    /// Inliers of the last pose optimisation.
    pub inliers: usize,
    /// Keyframes that agreed, the detecting one included.
    pub confirmations: usize,
    /// Length of the translation of `T_into,merged` (metres): where the
    /// merged map's frame sits in the older map's.
    pub transform_m: f64,
    /// Its rotation (degrees).
    pub transform_deg: f64,
    /// Its scale: the older map's units per unit of the merged map (1 for
    /// stereo and RGB-D; a monocular map's own scale otherwise).
    pub scale: f64,
    /// The fusion and essential-graph correction that followed.
    pub correction: LoopCorrection,
}

/// A candidate that passed the descriptor stage and was rejected later.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RejectedLoopRecord {
    /// Input frame of the keyframe that looked for a loop.
    pub query_frame: usize,
    /// Input frame of the candidate keyframe.
    pub candidate_frame: usize,
    /// Its global-descriptor similarity.
    pub score: f32,
    /// The stage that rejected it.
    pub stage: LoopStage,
    /// The count reached there.
    pub count: usize,
    /// For a merge candidate, the older atlas map it is in.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub other_map: Option<usize>,
}

/// One loop or merge candidate's check, verified or not, with what each
/// stage counted (ORB-SLAM3's stages; `spslam run --record-loop-stages`
/// runs every stage): the data of the loop check's precision–recall curves.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LoopCandidateRecord {
    /// Input frame of the keyframe that looked for a loop.
    pub query_frame: usize,
    /// Input frame of the candidate keyframe.
    pub candidate_frame: usize,
    /// For a merge candidate, the older atlas map it is in.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub other_map: Option<usize>,
    /// Its global-descriptor similarity.
    pub score: f32,
    /// What each stage of the check counted.
    pub counts: LoopStageCounts,
    /// The stage that rejected it (`None`: every geometric stage passed).
    pub rejected_at: Option<LoopStage>,
    /// The candidate camera's centre in the query camera's frame at the
    /// last pose the check reached (metres), for a ground truth to judge.
    pub candidate_in_query: Option<[f64; 3]>,
}

impl LoopCandidateRecord {
    /// The record of `check`, whose keyframes are in `query_map` and
    /// `candidate_map`.
    fn new(
        check: &CandidateCheck,
        query_map: &Map,
        candidate_map: &Map,
        other_map: Option<usize>,
    ) -> Self {
        Self {
            query_frame: frame_of(query_map, check.query),
            candidate_frame: frame_of(candidate_map, check.candidate),
            other_map,
            score: check.score,
            counts: check.counts,
            rejected_at: check.rejected_at,
            candidate_in_query: check.candidate_in_query,
        }
    }
}

/// What the check of one keyframe accepted.
#[derive(Debug, Clone)]
pub(crate) enum Detection {
    /// A loop in the active map.
    Loop(AcceptedLoop),
    /// A common place with an older map.
    Merge(AcceptedMerge),
}

/// Keyframes waiting for the loop check, the detector and what it found.
#[derive(Debug)]
pub(crate) struct LoopClosingStage {
    detector: LoopDetector,
    merger: MergeDetector,
    queue: VecDeque<KeyFrameId>,
}

/// What the check of one queued keyframe gave.
#[derive(Debug, Default)]
pub(crate) struct DetectStep {
    /// What to correct, if anything.
    pub(crate) detection: Option<Detection>,
    /// Candidates rejected after the descriptor stage.
    pub(crate) rejected: Vec<RejectedLoopRecord>,
    /// Every candidate checked.
    pub(crate) candidates: Vec<LoopCandidateRecord>,
}

/// Every loop, merge and rejected candidate of a run, in order.
#[derive(Debug, Default)]
pub(crate) struct LoopLog {
    pub(crate) loops: Vec<LoopRecord>,
    pub(crate) merges: Vec<MergeRecord>,
    pub(crate) rejected: Vec<RejectedLoopRecord>,
    /// Every candidate's check, kept only when asked for
    /// ([`LoopThresholds::record_every_stage`]): a long run would otherwise
    /// grow it without bound.
    pub(crate) candidates: Vec<LoopCandidateRecord>,
    /// Whether `candidates` is kept (set when loop closing is enabled).
    pub(crate) keep_candidates: bool,
}

impl LoopLog {
    /// Keeps what one detection step recorded of its candidates.
    pub(crate) fn record(
        &mut self,
        rejected: Vec<RejectedLoopRecord>,
        candidates: Vec<LoopCandidateRecord>,
    ) {
        self.rejected.extend(rejected);
        if self.keep_candidates {
            self.candidates.extend(candidates);
        }
    }
}

/// The input frame of a keyframe (live or not: 0 when unknown).
fn frame_of(map: &Map, kf: KeyFrameId) -> usize {
    map.keyframe(kf).map_or(0, |k| k.frame_index)
}

impl LoopClosingStage {
    /// A stage with an empty database.
    pub(crate) fn new(
        descriptor: Arc<dyn GlobalDescriptor>,
        thresholds: LoopThresholds,
    ) -> Result<Self, SlamError> {
        Ok(Self {
            detector: LoopDetector::new(descriptor, thresholds)?,
            merger: MergeDetector::new(thresholds),
            queue: VecDeque::new(),
        })
    }

    /// Queues a keyframe local mapping has processed.
    pub(crate) fn push(&mut self, kf: KeyFrameId) {
        self.queue.push_back(kf);
    }

    /// Starts over on a new map: the database of the map left
    /// (`finished`) is archived for merging, the queue emptied;
    /// `handover` (where the camera was lost in `finished`) judges a merge
    /// back into it.
    pub(crate) fn new_map(
        &mut self,
        finished: usize,
        handover: Option<Handover>,
    ) -> Result<(), SlamError> {
        self.queue.clear();
        let database = self.detector.take_database()?;
        self.merger.archive(finished, database);
        self.merger.start_map(handover);
        Ok(())
    }

    /// Indexes the maps of a loaded atlas (atlas index, map): the active
    /// one's keyframes fill the database (relocalisation and loops), the
    /// others' are archived for merging.
    pub(crate) fn index_loaded(
        &mut self,
        maps: &[(usize, &Map)],
        active: usize,
    ) -> Result<(), SlamError> {
        self.reset()?;
        for (index, map) in maps {
            let database = self.detector.database_of(map)?;
            if *index == active {
                self.detector.replace_database(database)?;
            } else {
                self.merger.archive(*index, database);
            }
        }
        Ok(())
    }

    /// Starts over with an empty atlas: every database emptied.
    pub(crate) fn reset(&mut self) -> Result<(), SlamError> {
        self.queue.clear();
        self.merger.clear();
        self.detector.clear()
    }

    /// The detector's keyframe database, shared (relocalisation queries it;
    /// [`Self::new_map`] empties it in place).
    pub(crate) fn shared_database(&self) -> SharedKeyframeDatabase {
        self.detector.shared_database()
    }

    /// Checks the next queued keyframe of `map` for a loop, then, when
    /// none is found, against the older maps `others` (atlas index → map)
    /// for a merge; returns what to correct with [`Self::correct`] or
    /// [`Self::merge`], or `None` (also when the queue is empty: see
    /// [`Self::has_queued`]).
    pub(crate) fn detect_next(
        &mut self,
        map: &SharedMap,
        others: &BTreeMap<usize, SharedMap>,
        rig: &CameraRig,
    ) -> Result<DetectStep, SlamError> {
        let mut step = DetectStep::default();
        let Some(kf) = self.queue.pop_front() else {
            return Ok(step);
        };
        // One short read lock per detection step, none across the whole
        // detection; a candidate's check holds it only to copy what it
        // reads, then runs on the copy.
        let read = || map.read().map_err(|_| SlamError::PoisonedMap);
        let outcome = self.detector.process_with(read, kf, rig)?;
        let map = map.read().map_err(|_| SlamError::PoisonedMap)?;
        for c in &outcome.checks {
            step.candidates
                .push(LoopCandidateRecord::new(c, &map, &map, None));
        }
        for r in outcome.rejected {
            step.rejected.push(RejectedLoopRecord {
                query_frame: frame_of(&map, r.query),
                candidate_frame: frame_of(&map, r.candidate),
                score: r.score,
                stage: r.stage,
                count: r.count,
                other_map: None,
            });
        }
        if let Some(accepted) = outcome.accepted {
            step.detection = Some(Detection::Loop(accepted));
            return Ok(step);
        }
        if !self.merger.has_archived() {
            return Ok(step);
        }
        let Some(descriptor) = outcome.descriptor else {
            return Ok(step);
        };
        drop(map);
        // The same for the merge check: short read locks per step, on the
        // active map and on the older map at hand.
        let read_other = |tag: usize| {
            others
                .get(&tag)
                .map(|m| m.read().map_err(|_| SlamError::PoisonedMap))
        };
        let outcome = self
            .merger
            .process(read, kf, &descriptor, read_other, rig)?;
        let map = read()?;
        for (tag, c) in &outcome.checks {
            if let Some(other) = read_other(*tag) {
                let other = other?;
                step.candidates
                    .push(LoopCandidateRecord::new(c, &map, &other, Some(*tag)));
            }
        }
        for (tag, r) in outcome.rejected {
            let candidate_frame = match read_other(tag) {
                Some(other) => frame_of(&*other?, r.candidate),
                None => 0,
            };
            step.rejected.push(RejectedLoopRecord {
                query_frame: frame_of(&map, r.query),
                candidate_frame,
                score: r.score,
                stage: r.stage,
                count: r.count,
                other_map: Some(tag),
            });
        }
        step.detection = outcome.accepted.map(Detection::Merge);
        Ok(step)
    }

    /// Merges the active map (`active`, atlas index `active_index`) into
    /// the older map of an accepted merge (`target`): the active map's
    /// keyframes and points move into the older map's frame and units
    /// (`Map::absorb`, a similarity for a monocular map; `active` is left
    /// empty), the duplicates are fused
    /// and the essential graph optimised ([`correct_loop`]), and the two
    /// keyframe databases become one. Local mapping must not run meanwhile.
    /// `Ok(None)` when the matched keyframes were culled since the check
    /// (the merge waits for the next detection).
    pub(crate) fn merge(
        &mut self,
        active: &SharedMap,
        active_index: usize,
        target: &SharedMap,
        accepted: &AcceptedMerge,
        rig: &CameraRig,
    ) -> Result<Option<MergeRecord>, SlamError> {
        let mut from = active.write().map_err(|_| SlamError::PoisonedMap)?;
        let mut into = target.write().map_err(|_| SlamError::PoisonedMap)?;
        let common = &accepted.common;
        if from.keyframe(common.query).is_err() || into.keyframe(common.candidate).is_err() {
            return Ok(None);
        }
        let query_frame = frame_of(&from, common.query);
        let match_frame = frame_of(&into, common.candidate);
        into.absorb(
            &mut from,
            &accepted.t_target_active,
            (common.query, common.candidate),
        )
        .in_stage("map merge")?;
        let correction = correct_loop(&mut into, common, rig)?;
        let mut database = self
            .merger
            .take_archived(accepted.target)
            .map_or_else(|| self.detector.take_database(), Ok)?;
        database
            .absorb(self.detector.take_database()?)
            .in_stage("keyframe database merge")?;
        self.detector.replace_database(database)?;
        let transform = &accepted.t_target_active;
        let (transform_m, transform_deg) = pose_difference(
            &Se3::identity(),
            &Se3::new(transform.rotation, transform.translation),
        );
        let record = MergeRecord {
            query_frame,
            match_frame,
            merged_map: active_index,
            into_map: accepted.target,
            inliers: common.inliers,
            confirmations: common.confirmations,
            transform_m,
            transform_deg,
            scale: transform.scale,
            correction,
        };
        tracing::info!(
            query_frame,
            match_frame,
            merged_map = active_index,
            into_map = accepted.target,
            inliers = common.inliers,
            transform_m,
            scale = transform.scale,
            "maps merged"
        );
        Ok(Some(record))
    }

    /// Whether keyframes wait for the check.
    pub(crate) fn has_queued(&self) -> bool {
        !self.queue.is_empty()
    }

    /// Corrects the map with an accepted loop (local mapping must not run
    /// meanwhile). `Ok(None)` when the two keyframes were culled since the
    /// check (the loop waits for the next detection).
    pub(crate) fn correct(
        &mut self,
        map: &SharedMap,
        accepted: &AcceptedLoop,
        rig: &CameraRig,
    ) -> Result<Option<LoopRecord>, SlamError> {
        let mut map = map.write().map_err(|_| SlamError::PoisonedMap)?;
        if map.keyframe(accepted.query).is_err() || map.keyframe(accepted.candidate).is_err() {
            return Ok(None);
        }
        let (query_frame, match_frame) = (
            frame_of(&map, accepted.query),
            frame_of(&map, accepted.candidate),
        );
        let correction = correct_loop(&mut map, accepted, rig)?;
        let record = LoopRecord {
            query_frame,
            match_frame,
            inliers: accepted.inliers,
            correction_m: correction.correction_m,
            correction_deg: correction.correction_deg,
            confirmations: accepted.confirmations,
            correction,
        };
        tracing::info!(
            query_frame,
            match_frame,
            inliers = accepted.inliers,
            correction_m = correction.correction_m,
            correction_deg = correction.correction_deg,
            "loop closed"
        );
        Ok(Some(record))
    }
}
