//! Loop detection over a map's keyframes, one keyframe at a time, as
//! ORB-SLAM3's `LoopClosing::NewDetectCommonRegions` (stereo: SE3):
//!
//! 1. the keyframe's global descriptor queries the keyframe database,
//!    excluding its covisible keyframes and theirs;
//! 2. each candidate gets the multi-stage check of [`verify_candidate`];
//! 3. the first verified candidate gives a correction `C` (the keyframe's
//!    pose moves from `T_qw` to `T_qw·C`); it must be confirmed by
//!    [`LoopThresholds::confirmations`] keyframes in all: the detecting one,
//!    its covisible keyframes moved by `C`, and, while it is pending, the
//!    next keyframes (up to [`LoopThresholds::max_misses`] may fail);
//! 4. the keyframe is inserted into the database.
//!
//! Read only on the map: the caller corrects the map with the accepted loop.
//!
//! The database is shared ([`SharedKeyframeDatabase`]): relocalisation
//! queries it too ([`super::DatabaseRelocaliser`]). It is locked only for
//! one insert, erase or query at a time, and cleared in place on a new map
//! so that every holder sees the same one.

use std::collections::HashSet;
use std::sync::{Arc, RwLock, RwLockReadGuard, RwLockWriteGuard};

use crate::camera::CameraRig;
use crate::error::{MapContext, SlamError};
use crate::features::DescriptorSet;
use crate::map::{KeyFrameId, Map, MapPointId};
use crate::optim::{Se3, Sim3};
use crate::place::{GlobalDescriptor, KeyframeDatabase, QueryOptions};

use super::drift::loop_travel;
use super::stage_counts::{CandidateCheck, LoopStage};
use super::streak::CandidateStreak;
use super::thresholds::LoopThresholds;
use super::verify::{
    candidate_group, check_candidate, confirm_with, detach_group, detach_query, CandidateGroup,
    CheckedCandidate, RejectedCandidate, VerifiedLoop,
};

/// A loop the detector accepted: the query keyframe's pose in the loop's
/// frame and its matches with the loop group.
#[derive(Debug, Clone)]
pub struct AcceptedLoop {
    /// The keyframe whose check accepted it (the last confirmer).
    pub query: KeyFrameId,
    /// The loop keyframe (the verified candidate).
    pub candidate: KeyFrameId,
    /// The candidate and its covisible keyframes.
    pub group: Vec<KeyFrameId>,
    /// The query's corrected pose `T_cw`.
    pub pose_cw: Se3,
    /// Per query keypoint: the group's point matched to it.
    pub matches: Vec<Option<MapPointId>>,
    /// Inliers of the query's last optimisation.
    pub inliers: usize,
    /// Keyframes that agreed, the detecting one included.
    pub confirmations: usize,
}

impl AcceptedLoop {
    /// The loop `verified` for keyframe `query`, with `confirmations`.
    pub fn from_verified(query: KeyFrameId, verified: VerifiedLoop, confirmations: usize) -> Self {
        Self {
            query,
            candidate: verified.candidate,
            group: verified.group,
            pose_cw: verified.pose_cw,
            matches: verified.matches,
            inliers: verified.inliers,
            confirmations,
        }
    }
}

/// What one keyframe's detection found.
#[derive(Debug, Clone, Default)]
pub struct DetectionOutcome {
    /// The loop to correct now, if any.
    pub accepted: Option<AcceptedLoop>,
    /// Candidates rejected after the descriptor stage.
    pub rejected: Vec<RejectedCandidate>,
    /// Every candidate checked, with what each stage counted.
    pub checks: Vec<CandidateCheck>,
    /// The keyframe's global descriptor (`None` without float rows), for
    /// the merge check that may follow.
    pub descriptor: Option<Vec<f32>>,
}

/// What [`LoopDetector::process_with`] does with a keyframe after its global descriptor.
#[derive(Debug, Clone, PartialEq)]
pub enum DetectionPlan {
    /// Nothing: the map has too few keyframes for a loop.
    Nothing,
    /// Confirm the pending loop ([`LoopDetector::confirm_pending`]).
    Confirm,
    /// Check these candidates, best first ([`LoopDetector::verify_candidate`]),
    /// until one is verified.
    Candidates(Vec<(KeyFrameId, f32)>),
}

/// What checking one candidate gave.
#[derive(Debug, Clone)]
pub enum CandidateStep {
    /// Rejected: go on with the next candidate.
    Rejected,
    /// Verified, waiting for confirmations: stop checking candidates.
    Pending,
    /// Verified with enough confirmations: correct it.
    Accepted(AcceptedLoop),
}

/// A verified loop waiting for confirmations (in a [`CandidateStreak`]).
#[derive(Debug, Clone)]
struct PendingLoop {
    candidate: KeyFrameId,
    score: f32,
    query: KeyFrameId,
    group: Vec<KeyFrameId>,
    group_points: Vec<MapPointId>,
    correction: Sim3,
}

/// What one candidate's check reads, copied out of the map under a short
/// read lock ([`LoopDetector::verify_candidate`]).
struct DetachedCheck {
    /// The query keyframe and the covisible keyframes that may confirm it
    /// (copied once per detection, shared by its candidates).
    query_side: Arc<Map>,
    /// The candidate's group.
    group: CandidateGroup,
    /// A copy of the group's points.
    points: Map,
}

/// The keyframe database of one map, shared by loop detection (which
/// fills it) and relocalisation (which queries it).
pub type SharedKeyframeDatabase = Arc<RwLock<KeyframeDatabase<KeyFrameId>>>;

/// Reads the shared database. A poisoned lock (a thread panicked while
/// writing it; in threaded mode loop detection and relocalisation run on
/// different threads) is [`SlamError::PoisonedKeyframeDatabase`], as a
/// poisoned map is [`SlamError::PoisonedMap`].
pub(super) fn read_database(
    database: &SharedKeyframeDatabase,
) -> Result<RwLockReadGuard<'_, KeyframeDatabase<KeyFrameId>>, SlamError> {
    database
        .read()
        .map_err(|_| SlamError::PoisonedKeyframeDatabase)
}

/// Writes the shared database (a poisoned lock as in [`read_database`]).
pub(super) fn write_database(
    database: &SharedKeyframeDatabase,
) -> Result<RwLockWriteGuard<'_, KeyframeDatabase<KeyFrameId>>, SlamError> {
    database
        .write()
        .map_err(|_| SlamError::PoisonedKeyframeDatabase)
}

/// The detector's state: the database and a pending loop.
pub struct LoopDetector {
    descriptor: Arc<dyn GlobalDescriptor>,
    database: SharedKeyframeDatabase,
    thresholds: LoopThresholds,
    pending: Option<CandidateStreak<PendingLoop>>,
}

impl std::fmt::Debug for LoopDetector {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LoopDetector")
            .field("keyframes", &self.database_len())
            .field("thresholds", &self.thresholds)
            .field("pending", &self.pending.is_some())
            .finish()
    }
}

/// The float rows of a keyframe or frame, when it has float descriptors.
pub(super) fn float_rows(descriptors: &DescriptorSet) -> Option<&[f32]> {
    match descriptors {
        DescriptorSet::Float { data, .. } if !data.is_empty() => Some(data),
        _ => None,
    }
}

impl LoopDetector {
    /// A detector with an empty database.
    pub fn new(
        descriptor: Arc<dyn GlobalDescriptor>,
        thresholds: LoopThresholds,
    ) -> Result<Self, SlamError> {
        let database = KeyframeDatabase::new(descriptor.dim()).in_stage("keyframe database")?;
        Ok(Self {
            descriptor,
            database: Arc::new(RwLock::new(database)),
            thresholds,
            pending: None,
        })
    }

    /// The thresholds.
    pub fn thresholds(&self) -> &LoopThresholds {
        &self.thresholds
    }

    /// Keyframes in the database.
    pub fn database_len(&self) -> Result<usize, SlamError> {
        Ok(read_database(&self.database)?.len())
    }

    /// The database, shared (for relocalisation, see
    /// [`super::DatabaseRelocaliser`]); [`Self::clear`] empties this same one.
    pub fn shared_database(&self) -> SharedKeyframeDatabase {
        Arc::clone(&self.database)
    }

    /// Forgets every keyframe and the pending loop (a new map). The
    /// database is emptied in place: its sharers see the empty one.
    pub fn clear(&mut self) -> Result<(), SlamError> {
        self.take_database().map(|_| ())
    }

    /// Takes the database's entries out (a map the system leaves, kept for
    /// merging), leaving it empty in place, and forgets the pending loop.
    pub fn take_database(&mut self) -> Result<KeyframeDatabase<KeyFrameId>, SlamError> {
        let empty = KeyframeDatabase::new(self.descriptor.dim()).in_stage("keyframe database")?;
        self.pending = None;
        Ok(std::mem::replace(
            &mut *write_database(&self.database)?,
            empty,
        ))
    }

    /// Replaces the database's entries in place (a merge made another map
    /// active) and forgets the pending loop.
    pub fn replace_database(
        &mut self,
        database: KeyframeDatabase<KeyFrameId>,
    ) -> Result<(), SlamError> {
        *write_database(&self.database)? = database;
        self.pending = None;
        Ok(())
    }

    /// A database of every keyframe of `map` (a loaded map), in id order.
    pub fn database_of(&self, map: &Map) -> Result<KeyframeDatabase<KeyFrameId>, SlamError> {
        let mut database =
            KeyframeDatabase::new(self.descriptor.dim()).in_stage("keyframe database")?;
        for kf in map.keyframes() {
            if let Some(d) = self.describe(map, kf.id())? {
                database
                    .insert(kf.id(), &d)
                    .in_stage("keyframe database insert")?;
            }
        }
        Ok(database)
    }

    /// The global descriptor of a keyframe; `None` without float rows
    /// (binary descriptors: no VLAD codebook applies).
    pub fn describe(&self, map: &Map, kf: KeyFrameId) -> Result<Option<Vec<f32>>, SlamError> {
        match keyframe_rows(map, kf) {
            Some(rows) => self.describe_rows(rows),
            None => Ok(None),
        }
    }

    /// The global descriptor of a keyframe's descriptor rows (row-major
    /// floats); `None` when they do not fit the codebook's width.
    fn describe_rows(&self, rows: &[f32]) -> Result<Option<Vec<f32>>, SlamError> {
        if !rows.len().is_multiple_of(self.descriptor.local_dim()) {
            return Ok(None);
        }
        self.descriptor
            .compute_flat(rows)
            .map(Some)
            .in_stage("global descriptor")
    }

    /// The database's best candidates for a global descriptor, excluding
    /// `exclude` (relocalisation uses this too).
    pub fn candidates(
        &self,
        map: &Map,
        descriptor: &[f32],
        exclude: &HashSet<KeyFrameId>,
        n_best: usize,
    ) -> Result<Vec<(KeyFrameId, f32)>, SlamError> {
        let options = QueryOptions {
            n_best,
            group_size: self.thresholds.group_size,
            ..QueryOptions::default()
        };
        Ok(read_database(&self.database)?
            .query(descriptor, exclude, |k| map.best_covisible(k, 10), &options)
            .in_stage("keyframe database query")?
            .into_iter()
            .map(|c| (c.keyframe, c.score))
            .collect())
    }

    /// Drops culled keyframes from the database.
    fn forget_culled(&mut self, map: &Map) -> Result<(), SlamError> {
        let mut database = write_database(&self.database)?;
        let gone: Vec<KeyFrameId> = database
            .keyframes()
            .filter(|k| map.keyframe(*k).is_err())
            .collect();
        for k in gone {
            database.erase(k);
        }
        Ok(())
    }

    /// Looks for a loop at keyframe `kf` (see the module's docs) and adds
    /// it to the database, all on one map ([`Self::process_with`]).
    pub fn process(
        &mut self,
        map: &Map,
        kf: KeyFrameId,
        rig: &CameraRig,
    ) -> Result<DetectionOutcome, SlamError> {
        self.process_with(|| Ok(map), kf, rig)
    }

    /// The detection's steps: the keyframe's global descriptor and the
    /// database query, then [`Self::confirm_pending`]
    /// or [`Self::verify_candidate`] for each candidate until one is
    /// verified, then [`Self::record`]. `read` gives the map for one step;
    /// a caller that shares the map with other threads passes a read lock,
    /// so that the lock is held for one step at a time (the system's
    /// loop-closing stage does), never across the whole detection. A
    /// candidate's check, the long step, holds it only while copying what
    /// it reads ([`Map::excerpt`]: the query and its confirming keyframes,
    /// the candidate group's points) and then runs on the copies.
    pub fn process_with<M: std::ops::Deref<Target = Map>>(
        &mut self,
        read: impl Fn() -> Result<M, SlamError>,
        kf: KeyFrameId,
        rig: &CameraRig,
    ) -> Result<DetectionOutcome, SlamError> {
        let mut outcome = DetectionOutcome::default();
        // The keyframe's global descriptor (a few ms) is computed from a
        // copy of its descriptor rows, outside the lock.
        let rows = {
            let map = read()?;
            self.forget_culled(&map)?;
            keyframe_rows(&map, kf).map(<[f32]>::to_vec)
        };
        let Some(descriptor) = rows
            .map(|rows| self.describe_rows(&rows))
            .transpose()?
            .flatten()
        else {
            return Ok(outcome);
        };
        let plan = self.plan_for(&*read()?, kf, &descriptor)?;
        match plan {
            DetectionPlan::Confirm => {
                // The keyframe and the pending group's points are copied
                // under a short read lock; the confirmation (a search by
                // projection and a pose optimisation) holds none.
                let detached = match &self.pending {
                    Some(p) => read()?.excerpt(&[kf], &p.subject.group_points),
                    None => Map::default(),
                };
                outcome.accepted =
                    self.confirm_pending(&detached, kf, rig, &mut outcome.rejected)?;
            }
            DetectionPlan::Candidates(candidates) => {
                let mut query_side = None;
                for candidate in candidates {
                    // What the check reads is copied under one short read
                    // lock; the check itself (tens of ms) holds none.
                    let Some(detached) =
                        self.detach(&*read()?, (kf, candidate.0), rig, query_side.as_ref())
                    else {
                        continue;
                    };
                    query_side = Some(Arc::clone(&detached.query_side));
                    let step = self.check_group(
                        &detached.query_side,
                        kf,
                        (&detached.group, &detached.points),
                        candidate.1,
                        rig,
                        (&mut outcome.rejected, &mut outcome.checks),
                    )?;
                    match step {
                        CandidateStep::Rejected => continue,
                        CandidateStep::Pending => break,
                        CandidateStep::Accepted(accepted) => {
                            outcome.accepted = Some(accepted);
                            break;
                        }
                    }
                }
            }
            DetectionPlan::Nothing => {}
        }
        self.record(kf, &descriptor)?;
        outcome.descriptor = Some(descriptor);
        Ok(outcome)
    }

    /// The first step's plan for keyframe `kf` with global descriptor
    /// `descriptor` (short: the database query): confirm the pending loop,
    /// or check the database's candidates.
    fn plan_for(
        &self,
        map: &Map,
        kf: KeyFrameId,
        descriptor: &[f32],
    ) -> Result<DetectionPlan, SlamError> {
        Ok(if self.pending.is_some() {
            DetectionPlan::Confirm
        } else if map.keyframe_count() >= self.thresholds.min_keyframes {
            let exclude = Self::neighbourhood(map, kf);
            let candidates =
                self.candidates(map, descriptor, &exclude, self.thresholds.candidates)?;
            DetectionPlan::Candidates(candidates)
        } else {
            DetectionPlan::Nothing
        })
    }

    /// The last step: keyframe `kf` enters the database with its global
    /// descriptor.
    pub fn record(&mut self, kf: KeyFrameId, descriptor: &[f32]) -> Result<(), SlamError> {
        write_database(&self.database)?
            .insert(kf, descriptor)
            .in_stage("keyframe database insert")
    }

    /// The keyframes a query from `kf` must not return: itself, its
    /// covisible keyframes and theirs.
    fn neighbourhood(map: &Map, kf: KeyFrameId) -> HashSet<KeyFrameId> {
        let mut exclude: HashSet<KeyFrameId> = HashSet::from([kf]);
        for n in map.best_covisible(kf, usize::MAX) {
            exclude.insert(n);
            exclude.extend(map.best_covisible(n, usize::MAX));
        }
        exclude
    }

    /// One candidate of [`DetectionPlan::Candidates`] (ORB-SLAM3's
    /// `DetectCommonRegionsFromBoW` for one candidate): the multi-stage
    /// check, then accepted (enough confirmations at once), pending (a
    /// streak starts; the other candidates are not checked) or rejected.
    /// A query or candidate culled since the plan is rejected quietly.
    pub fn verify_candidate(
        &mut self,
        map: &Map,
        kf: KeyFrameId,
        candidate: (KeyFrameId, f32),
        rig: &CameraRig,
        log: (&mut Vec<RejectedCandidate>, &mut Vec<CandidateCheck>),
    ) -> Result<CandidateStep, SlamError> {
        if map.keyframe(kf).is_err() || map.keyframe(candidate.0).is_err() {
            return Ok(CandidateStep::Rejected);
        }
        let mut group = candidate_group(map, candidate.0, self.thresholds.group_size);
        group.travel = loop_travel(map, candidate.0, kf, rig);
        self.check_group(map, kf, (&group, map), candidate.1, rig, log)
    }

    /// Copies what the check of `candidate` for `kf` reads (`None` when
    /// either was culled since the plan); the query's side is copied
    /// unless `query_side` (an earlier candidate's) is given.
    fn detach(
        &self,
        map: &Map,
        (kf, candidate): (KeyFrameId, KeyFrameId),
        rig: &CameraRig,
        query_side: Option<&Arc<Map>>,
    ) -> Option<DetachedCheck> {
        if map.keyframe(kf).is_err() || map.keyframe(candidate).is_err() {
            return None;
        }
        let (mut group, points) = detach_group(map, candidate, &self.thresholds);
        group.travel = loop_travel(map, candidate, kf, rig);
        let query_side = query_side
            .map(Arc::clone)
            .unwrap_or_else(|| Arc::new(detach_query(map, kf, &self.thresholds)));
        Some(DetachedCheck {
            query_side,
            group,
            points,
        })
    }

    /// [`Self::verify_candidate`] with the query in `query_map` and the
    /// group's points in `points_map` (the map itself, or the copies made
    /// by [`Self::detach`]).
    fn check_group(
        &mut self,
        query_map: &Map,
        kf: KeyFrameId,
        (group, points_map): (&CandidateGroup, &Map),
        score: f32,
        rig: &CameraRig,
        (rejected, checks): (&mut Vec<RejectedCandidate>, &mut Vec<CandidateCheck>),
    ) -> Result<CandidateStep, SlamError> {
        let th = self.thresholds;
        let candidate = group.candidate;
        let checked =
            match check_candidate(query_map, kf, (group, points_map), score, rig, &th, checks)? {
                Ok(checked) => checked,
                Err(record) => {
                    rejected.extend(record);
                    return Ok(CandidateStep::Rejected);
                }
            };
        let CheckedCandidate {
            verified,
            correction,
            group_points,
            confirmations,
        } = checked;
        tracing::debug!(
            keyframe = kf.0,
            candidate = candidate.0,
            inliers = verified.inliers,
            confirmations,
            "loop verified"
        );
        if confirmations >= th.confirmations {
            return Ok(CandidateStep::Accepted(AcceptedLoop::from_verified(
                kf,
                verified,
                confirmations,
            )));
        }
        self.pending = Some(CandidateStreak::start(
            PendingLoop {
                candidate,
                score,
                query: kf,
                group: verified.group,
                group_points,
                correction,
            },
            confirmations,
        ));
        Ok(CandidateStep::Pending)
    }

    /// The [`DetectionPlan::Confirm`] step: keyframe `kf` confirms the
    /// pending loop or misses it (ORB-SLAM3's
    /// `DetectAndReffineSim3FromLastKF`).
    pub fn confirm_pending(
        &mut self,
        map: &Map,
        kf: KeyFrameId,
        rig: &CameraRig,
        rejected: &mut Vec<RejectedCandidate>,
    ) -> Result<Option<AcceptedLoop>, SlamError> {
        let th = self.thresholds;
        let Some(mut streak) = self.pending.take() else {
            return Ok(None);
        };
        let pending = &streak.subject;
        let c = confirm_with(map, kf, &pending.correction, &pending.group_points, rig)?;
        if c.inliers >= th.min_confirmation_inliers {
            let confirmations = streak.confirm(1);
            if confirmations >= th.confirmations {
                let pending = streak.subject;
                return Ok(Some(AcceptedLoop {
                    query: kf,
                    candidate: pending.candidate,
                    group: pending.group,
                    pose_cw: c.pose_cw,
                    matches: c.matches,
                    inliers: c.inliers,
                    confirmations,
                }));
            }
        } else if streak.miss(th.max_misses) {
            let pending = &streak.subject;
            rejected.push(RejectedCandidate {
                query: pending.query,
                candidate: pending.candidate,
                score: pending.score,
                stage: LoopStage::Confirmation,
                count: streak.confirmations(),
            });
            return Ok(None);
        }
        self.pending = Some(streak);
        Ok(None)
    }
}

/// A live keyframe's descriptor rows (row-major floats); `None` when it is
/// culled or its descriptors are binary.
fn keyframe_rows(map: &Map, kf: KeyFrameId) -> Option<&[f32]> {
    let keyframe = map.keyframe(kf).ok()?;
    float_rows(&keyframe.measurements.descriptors)
}
