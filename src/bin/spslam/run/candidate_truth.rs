//! Loop and merge candidates (`spslam run --record-loop-stages`) against the
//! ground truth. A candidate that reached a pose is judged by its
//! registration: where the check put the candidate camera in the query
//! camera's frame, against where the ground truth has it. A right loop
//! registers within centimetres (the local map's error); a look-alike
//! registers metres off, wherever the two frames are. Monocular runs (scale
//! free) and candidates without a RANSAC pose are not judged.

use serde::Serialize;

use spslam::eval::place_recognition::CandidateTruth;
use spslam::eval::Trajectory;
use spslam::system::LoopCandidateRecord;

use super::evaluation::CONSISTENT_LINK_M;

/// A registration this far off the truth (m) or more is wrong: the
/// candidate shows another place, or the check matched the wrong points.
/// Between [`CONSISTENT_LINK_M`] and this it is neither right nor wrong
/// ([`CandidateTruth::Ambiguous`]).
pub const WRONG_REGISTRATION_M: f64 = 3.0;

/// One candidate's record with its judgement.
#[derive(Debug, Clone, Serialize)]
pub struct JudgedCandidate<'a> {
    /// What the run recorded.
    #[serde(flatten)]
    pub record: &'a LoopCandidateRecord,
    /// The true distance between the query and candidate cameras, m.
    pub distance_m: Option<f64>,
    /// How far the check's `candidate_in_query` is from the truth's, m.
    pub registration_error_m: Option<f64>,
    /// Right ([`CandidateTruth::Same`]: within [`CONSISTENT_LINK_M`]),
    /// wrong ([`CandidateTruth::Different`]: beyond
    /// [`WRONG_REGISTRATION_M`]) or in between.
    pub truth: Option<CandidateTruth>,
}

/// The truth of a registration `error_m` off.
pub fn registration_truth(error_m: f64) -> CandidateTruth {
    if error_m <= CONSISTENT_LINK_M {
        CandidateTruth::Same
    } else if error_m > WRONG_REGISTRATION_M {
        CandidateTruth::Different
    } else {
        CandidateTruth::Ambiguous
    }
}

/// Judges `records` against `gt`; `gt_row` gives the ground-truth row of
/// an input frame (`None`: not in the truth). Without a metric scale
/// (`metric` false) only the distance is given.
pub fn judge_candidates<'a>(
    records: &'a [LoopCandidateRecord],
    gt: &Trajectory,
    gt_row: impl Fn(usize) -> Option<usize>,
    metric: bool,
) -> Vec<JudgedCandidate<'a>> {
    records
        .iter()
        .map(|record| {
            let rows = gt_row(record.query_frame).zip(gt_row(record.candidate_frame));
            let truth_in_query = rows.map(|(q, c)| {
                let (query, candidate) = (&gt.poses[q], &gt.poses[c]);
                query.inverse_transform_vector(
                    &(candidate.translation.vector - query.translation.vector),
                )
            });
            let registration_error_m = truth_in_query
                .zip(record.candidate_in_query)
                .filter(|_| metric)
                .map(|(truth, [x, y, z])| (truth - nalgebra::Vector3::new(x, y, z)).norm());
            JudgedCandidate {
                record,
                distance_m: truth_in_query.map(|t| t.norm()),
                registration_error_m,
                truth: registration_error_m.map(registration_truth),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
    use spslam::loop_closing::LoopStageCounts;

    fn record(
        query_frame: usize,
        candidate_frame: usize,
        at: Option<[f64; 3]>,
    ) -> LoopCandidateRecord {
        LoopCandidateRecord {
            query_frame,
            candidate_frame,
            other_map: None,
            score: 0.5,
            counts: LoopStageCounts::default(),
            rejected_at: None,
            candidate_in_query: at,
        }
    }

    #[test]
    fn a_registration_is_judged_in_the_query_cameras_frame() {
        // Both cameras turned 90° about y (optical axis along world x); the
        // candidate 2 m along world x: 2 m ahead of the query camera.
        let turn = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), std::f64::consts::FRAC_PI_2);
        let query = Isometry3::from_parts(Translation3::new(0.0, 0.0, 0.0), turn);
        let candidate = Isometry3::from_parts(Translation3::new(2.0, 0.0, 0.0), turn);
        let gt = Trajectory::new(vec![0.0, 1.0], vec![query, candidate]);
        let truth = query.inverse_transform_vector(&Vector3::new(2.0, 0.0, 0.0));
        assert!((truth - Vector3::new(0.0, 0.0, 2.0)).norm() < 1e-9);
        let near = [truth.x + 0.1, truth.y, truth.z];
        let off = [truth.x, truth.y + 5.0, truth.z];
        // The world-frame offset, not rotated into the camera.
        let unrotated = [2.0, 0.0, 0.0];
        let records = [
            record(0, 1, Some(near)),
            record(0, 1, Some(off)),
            record(0, 1, Some(unrotated)),
            record(0, 1, None),
            record(0, 7, Some(near)),
        ];
        let judged = judge_candidates(&records, &gt, |f| (f < 2).then_some(f), true);
        assert_eq!(judged[0].truth, Some(CandidateTruth::Same));
        assert!((judged[0].registration_error_m.unwrap() - 0.1).abs() < 1e-9);
        assert_eq!(judged[1].truth, Some(CandidateTruth::Different));
        // 2 m along x against 2 m along z: 2.83 m apart.
        assert_eq!(judged[2].truth, Some(CandidateTruth::Ambiguous));
        assert_eq!(judged[3].truth, None);
        assert!((judged[3].distance_m.unwrap() - 2.0).abs() < 1e-9);
        assert_eq!(judged[4].distance_m, None);
        let scale_free = judge_candidates(&records, &gt, |f| (f < 2).then_some(f), false);
        assert!(scale_free.iter().all(|j| j.truth.is_none()));
    }
}
