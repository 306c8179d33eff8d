//! The geometric check of one loop candidate (ORB-SLAM3's
//! `DetectCommonRegionsFromBoW` for a stereo map, scale fixed): descriptor
//! matches with the candidate's group, a RANSAC pose, pose optimisation,
//! two searches by projection; for the loop detector's checks, last,
//! whether the correction can be drift ([`super::drift`]). Read only: it
//! works on a [`Frame`] made from the query keyframe.

use std::collections::BTreeSet;

use crate::camera::{CameraRig, Sensor};
use crate::error::SlamError;
use crate::map::{KeyFrameId, Map, MapPointId};
use crate::optim::{LieGroup, Se3, Sim3};
use crate::tracking::{
    match_descriptors, match_projected, pnp_ransac, refine_pose, visible_in_frame, Frame,
    VisiblePoint, PNP_RANSAC_ITERATIONS,
};

use super::drift::{LoopDrift, Travel};
use super::side_scale::{corrected_pose, scaled_correction, side_scale};
use super::stage_counts::{CandidateCheck, LoopStage, LoopStageCounts};
use super::thresholds::LoopThresholds;

/// A candidate that passed the descriptor stage and failed later.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct RejectedCandidate {
    /// The keyframe that looked for a loop.
    pub query: KeyFrameId,
    /// The candidate.
    pub candidate: KeyFrameId,
    /// Its cosine similarity with the query.
    pub score: f32,
    /// Where it failed.
    pub stage: LoopStage,
    /// The count reached at that stage (matches, inliers or confirmations).
    pub count: usize,
}

/// A candidate that passed every geometric stage.
#[derive(Debug, Clone)]
pub struct VerifiedLoop {
    /// The candidate keyframe (the loop keyframe).
    pub candidate: KeyFrameId,
    /// The candidate and its covisible keyframes.
    pub group: Vec<KeyFrameId>,
    /// The query keyframe's pose `T_cw` in the loop's frame.
    pub pose_cw: Se3,
    /// Per query keypoint: the group's point matched to it.
    pub matches: Vec<Option<MapPointId>>,
    /// Inliers of the final optimisation.
    pub inliers: usize,
}

/// The outcome of one check: verified, or the stage that failed with the
/// count it reached.
#[derive(Debug, Clone)]
pub enum Verification {
    /// Every stage passed.
    Verified(VerifiedLoop),
    /// A stage failed.
    Rejected {
        /// Which one.
        stage: LoopStage,
        /// The count it reached.
        count: usize,
    },
}

/// A loop or merge candidate with its group: the candidate and its best
/// covisible keyframes, and the points they observe (resolved, in id order).
#[derive(Debug, Clone)]
pub(crate) struct CandidateGroup {
    /// The candidate keyframe.
    pub(crate) candidate: KeyFrameId,
    /// The candidate, then its best covisible keyframes.
    pub(crate) keyframes: Vec<KeyFrameId>,
    /// The points they observe.
    pub(crate) points: Vec<MapPointId>,
    /// The candidate's pose `T_cw` (`None` when culled).
    pub(crate) candidate_pose_cw: Option<Se3>,
    /// The way travelled from the candidate to the query, when the check
    /// judges the correction by it ([`LoopDrift`]): set by the loop
    /// detector ([`super::drift::loop_travel`]); `None` for a merge and for
    /// the bare geometric check ([`verify_candidate`]).
    pub(crate) travel: Option<Travel>,
}

/// The candidate and its best `size` covisible keyframes, and their points.
pub(crate) fn candidate_group(map: &Map, candidate: KeyFrameId, size: usize) -> CandidateGroup {
    let mut keyframes = vec![candidate];
    keyframes.extend(map.best_covisible(candidate, size));
    let mut points = BTreeSet::new();
    for kf in &keyframes {
        if let Ok(kf) = map.keyframe(*kf) {
            points.extend(
                kf.observed_points()
                    .filter_map(|(_, p)| map.resolve_point(p)),
            );
        }
    }
    CandidateGroup {
        candidate,
        keyframes,
        points: points.into_iter().collect(),
        candidate_pose_cw: map.pose_cw_of(candidate).ok(),
        travel: None,
    }
}

/// What a candidate's check ([`check_candidate`]) reads of the query's
/// map: the query keyframe and the covisible keyframes that may confirm
/// it, and the query's own points (a monocular check's scale compares
/// their depths with the other side's: [`side_scale`]), copied
/// ([`Map::excerpt`]) so that the check runs with no lock held.
pub(crate) fn detach_query(query_map: &Map, query: KeyFrameId, th: &LoopThresholds) -> Map {
    let mut keyframes = vec![query];
    keyframes.extend(query_map.best_covisible(query, th.confirming_covisibles));
    let own_points: Vec<MapPointId> = query_map
        .keyframe(query)
        .map(|kf| {
            kf.observed_points()
                .filter_map(|(_, p)| query_map.resolve_point(p))
                .collect()
        })
        .unwrap_or_default();
    query_map.excerpt(&keyframes, &own_points)
}

/// What a candidate's check reads of the candidate's map: its group, and
/// a copy of the group's points.
pub(crate) fn detach_group(
    map: &Map,
    candidate: KeyFrameId,
    th: &LoopThresholds,
) -> (CandidateGroup, Map) {
    let group = candidate_group(map, candidate, th.group_size);
    let points = map.excerpt(&[], &group.points);
    (group, points)
}

/// Searches `points` around their projections at the frame's pose.
fn search(
    frame: &mut Frame,
    map: &Map,
    points: &[MapPointId],
    rig: &CameraRig,
    radius: f32,
) -> Result<usize, SlamError> {
    let taken: BTreeSet<MapPointId> = frame.map_points.iter().flatten().copied().collect();
    let visible: Vec<VisiblePoint> = points
        .iter()
        .filter(|p| !taken.contains(p))
        .filter_map(|p| visible_in_frame(map, *p, frame, rig))
        .collect();
    match_projected(frame, map, &visible, radius, (1, 1), None)
}

/// Checks `candidate` for the query keyframe (see the module's docs): the
/// geometric stages only; the loop detector also judges the correction
/// against the way travelled ([`LoopDrift`]).
pub fn verify_candidate(
    map: &Map,
    query: KeyFrameId,
    candidate: KeyFrameId,
    rig: &CameraRig,
    th: &LoopThresholds,
) -> Result<Verification, SlamError> {
    verify_across(map, query, map, candidate, rig, th)
}

/// [`verify_candidate`] with the query keyframe in `query_map` and the
/// candidate in `map` (a merge candidate in another map of the atlas; the
/// same map for a loop). The pose found is the query's in `map`'s frame.
pub fn verify_across(
    query_map: &Map,
    query: KeyFrameId,
    map: &Map,
    candidate: KeyFrameId,
    rig: &CameraRig,
    th: &LoopThresholds,
) -> Result<Verification, SlamError> {
    Ok(verify_with_counts(query_map, query, map, candidate, rig, th)?.0)
}

/// [`verify_across`], with what each stage counted
/// ([`LoopThresholds::record_every_stage`] runs every stage).
pub fn verify_with_counts(
    query_map: &Map,
    query: KeyFrameId,
    map: &Map,
    candidate: KeyFrameId,
    rig: &CameraRig,
    th: &LoopThresholds,
) -> Result<(Verification, LoopStageCounts), SlamError> {
    let group = candidate_group(map, candidate, th.group_size);
    let check = verify_group(query_map, query, &group, map, rig, th)?;
    Ok((check.verification, check.counts))
}

/// What one candidate's check counted, its verdict, and the query's pose
/// at the last stage it reached.
struct GroupCheck {
    counts: LoopStageCounts,
    verification: Verification,
    /// The candidate camera's centre in the query camera's frame at that pose.
    candidate_in_query: Option<[f64; 3]>,
}

/// The check itself: the query keyframe (in `query_map`) against `group`,
/// whose points `points_map` holds (the candidate's map, or a copy of its
/// points: [`detach_group`]). It stops at the first stage that fails its
/// threshold, unless `th.record_every_stage` asks it to go on as far as
/// the geometry allows (a RANSAC pose is needed past that stage); the
/// verdict comes from the counts either way
/// ([`LoopStageCounts::first_failing`]).
fn verify_group(
    query_map: &Map,
    query: KeyFrameId,
    group: &CandidateGroup,
    points_map: &Map,
    rig: &CameraRig,
    th: &LoopThresholds,
) -> Result<GroupCheck, SlamError> {
    let mut counts = LoopStageCounts::default();
    let mut pose = None;
    run_stages(
        query_map,
        query,
        group,
        points_map,
        rig,
        th,
        &mut counts,
        &mut pose,
    )?;
    counts.drift = group
        .travel
        .zip(pose.as_ref())
        .zip(query_map.pose_cw_of(query).ok())
        .map(|((travel, (after_cw, _)), before_cw)| {
            LoopDrift::measure(travel, &before_cw, after_cw)
        });
    let candidate_in_query =
        pose.as_ref()
            .zip(group.candidate_pose_cw.as_ref())
            .map(|((query_cw, _), candidate_cw)| {
                let t = query_cw.compose(&candidate_cw.inverse()).translation;
                [t.x, t.y, t.z]
            });
    let verification = match counts.first_failing(th) {
        Some((stage, count)) => Verification::Rejected { stage, count },
        None => match pose {
            Some((pose_cw, matches)) => Verification::Verified(VerifiedLoop {
                candidate: group.candidate,
                group: group.keyframes.clone(),
                pose_cw,
                matches,
                inliers: counts.reprojection_inliers.unwrap_or(0),
            }),
            None => Verification::Rejected {
                stage: LoopStage::Ransac,
                count: 0,
            },
        },
    };
    Ok(GroupCheck {
        counts,
        verification,
        candidate_in_query,
    })
}

/// The query's pose `T_cw` in the candidate's frame and its matches, as
/// the stages leave them.
type CheckPose = Option<(Se3, Vec<Option<MapPointId>>)>;

/// The stages of [`verify_group`], filling `counts` and `pose` as far as
/// they go.
#[allow(clippy::too_many_arguments)]
fn run_stages(
    query_map: &Map,
    query: KeyFrameId,
    group: &CandidateGroup,
    points_map: &Map,
    rig: &CameraRig,
    th: &LoopThresholds,
    counts: &mut LoopStageCounts,
    pose: &mut CheckPose,
) -> Result<(), SlamError> {
    // Whether to go on after a stage: it passed, or every stage is asked for.
    let go_on = |counts: &LoopStageCounts, stage: LoopStage| {
        th.record_every_stage || counts.first_failing(th).is_none_or(|(s, _)| s != stage)
    };
    let Ok(query_kf) = query_map.keyframe(query) else {
        return Ok(());
    };
    let (map, points, candidate) = (points_map, &group.points, group.candidate);
    let mut frame = Frame::from_keyframe(query_kf, rig);
    frame.map_points.iter_mut().for_each(|p| *p = None);
    let matches = match_descriptors(&frame, map, points, th.match_ratio)?;
    counts.descriptor_matches = matches.len();
    if !go_on(counts, LoopStage::DescriptorMatches) {
        return Ok(());
    }
    let Some(ransac) = pnp_ransac(&frame, map, &matches, rig, PNP_RANSAC_ITERATIONS)? else {
        return Ok(());
    };
    counts.ransac_inliers = Some(ransac.inliers());
    frame.pose_cw = ransac.pose_cw;
    for (i, p) in &matches {
        frame.map_points[*i] = Some(*p);
    }
    *pose = Some((frame.pose_cw, frame.map_points.clone()));
    if !go_on(counts, LoopStage::Ransac) {
        return Ok(());
    }
    let optimised = refine_pose(&mut frame, map, rig)?;
    counts.optimised_inliers = Some(optimised);
    *pose = Some((frame.pose_cw, frame.map_points.clone()));
    if !go_on(counts, LoopStage::PoseOptimisation) {
        return Ok(());
    }
    let found = optimised + search(&mut frame, map, points, rig, 10.0)?;
    counts.projection_matches = Some(found);
    if !go_on(counts, LoopStage::Projection) {
        return Ok(());
    }
    refine_pose(&mut frame, map, rig)?;
    search(&mut frame, map, points, rig, 3.0)?;
    let matched = frame.tracked_count();
    let inliers = refine_pose(&mut frame, map, rig)?;
    counts.reprojection_inliers = Some(inliers);
    *pose = Some((frame.pose_cw, frame.map_points.clone()));
    tracing::debug!(
        query = query.0,
        candidate = candidate.0,
        descriptor_matches = matches.len(),
        ransac_inliers = ransac.inliers(),
        optimised,
        projection_matches = found,
        final_matches = matched,
        inliers,
        "loop candidate checked"
    );
    Ok(())
}

/// What a keyframe moved by the loop's correction sees of the group.
#[derive(Debug, Clone)]
pub struct Confirmation {
    /// Inliers after the search and the optimisation.
    pub inliers: usize,
    /// The keyframe's refined pose `T_cw` in the loop's frame.
    pub pose_cw: Se3,
    /// Per keypoint: the group's point matched to it.
    pub matches: Vec<Option<MapPointId>>,
}

/// Whether keyframe `kf`, moved by the loop's correction, sees the group's
/// points (ORB-SLAM3's `DetectAndReffineSim3FromLastKF`): its corrected
/// pose is `T_kw · correction` in the group's units
/// ([`corrected_pose`]); search window 8 px, then optimisation.
pub fn confirm_with(
    map: &Map,
    kf: KeyFrameId,
    correction: &Sim3,
    group_points: &[MapPointId],
    rig: &CameraRig,
) -> Result<Confirmation, SlamError> {
    confirm_across(map, kf, map, correction, group_points, rig)
}

/// [`confirm_with`] with keyframe `kf` in `query_map` and the group's
/// points in `map` (a merge: two maps of the atlas).
pub fn confirm_across(
    query_map: &Map,
    kf: KeyFrameId,
    map: &Map,
    correction: &Sim3,
    group_points: &[MapPointId],
    rig: &CameraRig,
) -> Result<Confirmation, SlamError> {
    let Ok(keyframe) = query_map.keyframe(kf) else {
        return Ok(Confirmation {
            inliers: 0,
            pose_cw: correction.to_se3_unscaled(),
            matches: Vec::new(),
        });
    };
    let mut frame = Frame::from_keyframe(keyframe, rig);
    frame.map_points.iter_mut().for_each(|p| *p = None);
    frame.pose_cw = corrected_pose(&keyframe.pose_cw(), correction);
    let found = search(&mut frame, map, group_points, rig, 8.0)?;
    let inliers = if found < 10 {
        0
    } else {
        refine_pose(&mut frame, map, rig)?
    };
    Ok(Confirmation {
        inliers,
        pose_cw: frame.pose_cw,
        matches: frame.map_points,
    })
}

/// A verified candidate with its correction and confirmations.
#[derive(Debug, Clone)]
pub(crate) struct CheckedCandidate {
    /// What the multi-stage check found.
    pub(crate) verified: VerifiedLoop,
    /// `C`: the query keyframe moves from `T_qw` to `T_qw·C`, in the
    /// group's units ([`scaled_correction`]; a monocular query side's
    /// scale is measured by [`side_scale`], 1 elsewhere).
    pub(crate) correction: Sim3,
    /// The candidate group's points.
    pub(crate) group_points: Vec<MapPointId>,
    /// The query and its covisible keyframes (outside the group) that see
    /// the group's points once moved by `C`.
    pub(crate) confirmations: usize,
}

/// The multi-stage check of `group`'s candidate (its points in
/// `points_map`) for keyframe `query` (in `query_map`; for a loop, both
/// the same map or copies of it: [`detach_query`], [`detach_group`]),
/// then the confirmation by the query's best covisible keyframes outside
/// the candidate's group. Every check is recorded in `checks`.
/// `Err(Some(record))` for a candidate rejected after the descriptor
/// stage (`score`: its retrieval similarity), `Err(None)` for one rejected
/// at it (not worth recording).
pub(crate) fn check_candidate(
    query_map: &Map,
    query: KeyFrameId,
    (group, points_map): (&CandidateGroup, &Map),
    score: f32,
    rig: &CameraRig,
    th: &LoopThresholds,
    checks: &mut Vec<CandidateCheck>,
) -> Result<Result<CheckedCandidate, Option<RejectedCandidate>>, SlamError> {
    let candidate = group.candidate;
    let check = verify_group(query_map, query, group, points_map, rig, th)?;
    let rejected_at = match &check.verification {
        Verification::Verified(_) => None,
        Verification::Rejected { stage, .. } => Some(*stage),
    };
    checks.push(CandidateCheck {
        query,
        candidate,
        score,
        counts: check.counts,
        rejected_at,
        candidate_in_query: check.candidate_in_query,
    });
    let verified = match check.verification {
        Verification::Verified(v) => v,
        Verification::Rejected { stage, count } => {
            let record = (stage != LoopStage::DescriptorMatches).then_some(RejectedCandidate {
                query,
                candidate,
                score,
                stage,
                count,
            });
            return Ok(Err(record));
        }
    };
    let query_pose = query_map
        .pose_cw_of(query)
        .map_err(|source| SlamError::Map {
            stage: "loop check",
            source,
        })?;
    // A monocular side's scale is its own (drift, or a map started after
    // a loss): the neighbours that confirm move in the group's units.
    let scale = if rig.sensor == Sensor::Monocular {
        side_scale(
            query_map,
            query,
            &query_pose,
            &verified.matches,
            points_map,
            &verified.pose_cw,
        )
        .unwrap_or(1.0)
    } else {
        1.0
    };
    let correction = scaled_correction(&query_pose, &verified.pose_cw, scale);
    let in_group: BTreeSet<KeyFrameId> = verified.group.iter().copied().collect();
    let mut confirmations = 1;
    for other in query_map
        .best_covisible(query, th.confirming_covisibles)
        .into_iter()
        .filter(|k| !in_group.contains(k))
    {
        let c = confirm_across(
            query_map,
            other,
            points_map,
            &correction,
            &group.points,
            rig,
        )?;
        if c.inliers >= th.min_confirmation_inliers {
            confirmations += 1;
        }
    }
    Ok(Ok(CheckedCandidate {
        verified,
        correction,
        group_points: group.points.clone(),
        confirmations,
    }))
}
