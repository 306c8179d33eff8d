//! The loop-closing stage of the system: every keyframe local mapping has
//! processed is checked for a loop ([`LoopDetector`]); an accepted loop is
//! corrected on the map ([`correct_loop`]) while local mapping is paused,
//! and recorded. The records name input frames, not keyframe ids.

use std::collections::VecDeque;
use std::sync::Arc;

use serde::Serialize;

use crate::camera::StereoRig;
use crate::error::SlamError;
use crate::loop_closing::{
    correct_loop, AcceptedLoop, LoopCorrection, LoopDetector, LoopStage, LoopThresholds,
    SharedKeyframeDatabase,
};
use crate::map::{KeyFrameId, Map, SharedMap};
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
}

/// Keyframes waiting for the loop check, the detector and what it found.
#[derive(Debug)]
pub(crate) struct LoopClosingStage {
    detector: LoopDetector,
    queue: VecDeque<KeyFrameId>,
    loops: Vec<LoopRecord>,
    rejected: Vec<RejectedLoopRecord>,
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
            queue: VecDeque::new(),
            loops: Vec::new(),
            rejected: Vec::new(),
        })
    }

    /// Queues a keyframe local mapping has processed.
    pub(crate) fn push(&mut self, kf: KeyFrameId) {
        self.queue.push_back(kf);
    }

    /// Starts over on a new map: the database and the queue are emptied;
    /// the records stay.
    pub(crate) fn new_map(&mut self) -> Result<(), SlamError> {
        self.queue.clear();
        self.detector.clear()
    }

    /// The detector's keyframe database, shared (relocalisation queries it;
    /// [`Self::new_map`] empties it in place).
    pub(crate) fn shared_database(&self) -> SharedKeyframeDatabase {
        self.detector.shared_database()
    }

    /// Accepted loops so far.
    pub(crate) fn loops(&self) -> &[LoopRecord] {
        &self.loops
    }

    /// Rejected candidates so far.
    pub(crate) fn rejected(&self) -> &[RejectedLoopRecord] {
        &self.rejected
    }

    /// Checks the next queued keyframe; returns an accepted loop, to be
    /// corrected with [`Self::correct`], or `None` (also when the queue is
    /// empty: see [`Self::has_queued`]).
    pub(crate) fn detect_next(
        &mut self,
        map: &SharedMap,
        rig: &StereoRig,
    ) -> Result<Option<AcceptedLoop>, SlamError> {
        let Some(kf) = self.queue.pop_front() else {
            return Ok(None);
        };
        let map = map.read().map_err(|_| SlamError::PoisonedMap)?;
        let outcome = self.detector.process(&map, kf, rig)?;
        for r in outcome.rejected {
            self.rejected.push(RejectedLoopRecord {
                query_frame: frame_of(&map, r.query),
                candidate_frame: frame_of(&map, r.candidate),
                score: r.score,
                stage: r.stage,
                count: r.count,
            });
        }
        Ok(outcome.accepted)
    }

    /// Whether keyframes wait for the check.
    pub(crate) fn has_queued(&self) -> bool {
        !self.queue.is_empty()
    }

    /// Corrects the map with an accepted loop (local mapping must not run
    /// meanwhile) and records it.
    pub(crate) fn correct(
        &mut self,
        map: &SharedMap,
        accepted: &AcceptedLoop,
        rig: &StereoRig,
    ) -> Result<LoopRecord, SlamError> {
        let mut map = map.write().map_err(|_| SlamError::PoisonedMap)?;
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
        self.loops.push(record);
        Ok(record)
    }
}
