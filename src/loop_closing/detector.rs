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
use crate::optim::Se3;
use crate::place::{GlobalDescriptor, KeyframeDatabase, QueryOptions};

use super::streak::CandidateStreak;
use super::thresholds::LoopThresholds;
use super::verify::{
    check_candidate, confirm_with, CheckedCandidate, LoopStage, RejectedCandidate,
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

/// What one keyframe's detection found.
#[derive(Debug, Clone, Default)]
pub struct DetectionOutcome {
    /// The loop to correct now, if any.
    pub accepted: Option<AcceptedLoop>,
    /// Candidates rejected after the descriptor stage.
    pub rejected: Vec<RejectedCandidate>,
    /// The keyframe's global descriptor (`None` without float rows), for
    /// the merge check that may follow.
    pub descriptor: Option<Vec<f32>>,
}

/// A verified loop waiting for confirmations (in a [`CandidateStreak`]).
#[derive(Debug, Clone)]
struct PendingLoop {
    candidate: KeyFrameId,
    score: f32,
    query: KeyFrameId,
    group: Vec<KeyFrameId>,
    group_points: Vec<MapPointId>,
    correction: Se3,
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
        let Ok(keyframe) = map.keyframe(kf) else {
            return Ok(None);
        };
        let Some(rows) = float_rows(&keyframe.measurements.descriptors) else {
            return Ok(None);
        };
        if rows.len() % self.descriptor.local_dim() != 0 {
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
    /// it to the database.
    pub fn process(
        &mut self,
        map: &Map,
        kf: KeyFrameId,
        rig: &CameraRig,
    ) -> Result<DetectionOutcome, SlamError> {
        self.forget_culled(map)?;
        let mut outcome = DetectionOutcome::default();
        let Some(descriptor) = self.describe(map, kf)? else {
            return Ok(outcome);
        };
        if self.pending.is_some() {
            outcome.accepted = self.confirm_pending(map, kf, rig, &mut outcome.rejected)?;
        } else if map.keyframe_count() >= self.thresholds.min_keyframes {
            outcome.accepted = self.detect(map, kf, &descriptor, rig, &mut outcome.rejected)?;
        }
        write_database(&self.database)?
            .insert(kf, &descriptor)
            .in_stage("keyframe database insert")?;
        outcome.descriptor = Some(descriptor);
        Ok(outcome)
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

    fn detect(
        &mut self,
        map: &Map,
        kf: KeyFrameId,
        descriptor: &[f32],
        rig: &CameraRig,
        rejected: &mut Vec<RejectedCandidate>,
    ) -> Result<Option<AcceptedLoop>, SlamError> {
        let th = self.thresholds;
        let exclude = Self::neighbourhood(map, kf);
        let candidates = self.candidates(map, descriptor, &exclude, th.candidates)?;
        for (candidate, score) in candidates {
            let checked = match check_candidate(map, kf, map, (candidate, score), rig, &th)? {
                Ok(checked) => checked,
                Err(record) => {
                    rejected.extend(record);
                    continue;
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
                return Ok(Some(AcceptedLoop {
                    query: kf,
                    candidate,
                    group: verified.group,
                    pose_cw: verified.pose_cw,
                    matches: verified.matches,
                    inliers: verified.inliers,
                    confirmations,
                }));
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
            return Ok(None);
        }
        Ok(None)
    }

    fn confirm_pending(
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
