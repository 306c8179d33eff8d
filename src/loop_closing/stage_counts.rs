//! What each stage of a loop candidate's check counted, and the one rule
//! that turns those counts into a verdict ([`LoopStageCounts::first_failing`]).
//!
//! The counts of a stage depend only on what the stages before it found,
//! never on a threshold, so a check that runs every stage
//! ([`LoopThresholds::record_every_stage`]) counts exactly what the
//! stopping check would have counted, and the verdict of any other
//! thresholds can be read off the record: the precision–recall curves of
//! `spslam evaluate` do this.

use crate::map::KeyFrameId;

use super::drift::LoopDrift;
use super::handover::HandoverGap;
use super::thresholds::LoopThresholds;

/// The stage at which a candidate failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LoopStage {
    /// Too few descriptor matches with the candidate group.
    DescriptorMatches,
    /// The RANSAC pose found too few inliers.
    Ransac,
    /// Too few inliers after optimising the pose on the matches.
    PoseOptimisation,
    /// Too few matches after the first search by projection.
    Projection,
    /// Too few inliers after the second search by projection.
    Reprojection,
    /// Every count passed, but the correction is more than drift explains
    /// ([`LoopDrift::excess`]; a monocular map's rotation only).
    Drift,
    /// A merge into the map the camera was lost from that passed every
    /// other stage, but places the new map further from where the camera
    /// was lost than it can have moved ([`HandoverGap::excess`]).
    Handover,
    /// Verified, but not confirmed by enough keyframes.
    Confirmation,
}

/// The count each stage of one candidate's check reached; `None` for a
/// stage that did not run (an earlier one stopped the check, or RANSAC
/// found no pose).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct LoopStageCounts {
    /// Descriptor matches with the candidate group.
    pub descriptor_matches: usize,
    /// Inliers of the RANSAC pose (`None`: no pose).
    pub ransac_inliers: Option<usize>,
    /// Inliers of the pose optimised on the matches.
    pub optimised_inliers: Option<usize>,
    /// Matches after the first search by projection (10 px).
    pub projection_matches: Option<usize>,
    /// Inliers after the second search (3 px) and the last optimisation.
    pub reprojection_inliers: Option<usize>,
    /// The correction the last pose asks for next to the way travelled
    /// since the candidate (`None`: no pose, or a merge).
    #[serde(default)]
    pub drift: Option<LoopDrift>,
    /// A merge into the map the camera was lost from: where it puts the
    /// new map next to where the camera was lost (`None`: a loop, a merge
    /// into another map, or no pose).
    #[serde(default)]
    pub handover: Option<HandoverGap>,
}

impl LoopStageCounts {
    /// The fraction of the descriptor matches the RANSAC pose explains.
    pub fn ransac_inlier_ratio(&self) -> Option<f32> {
        let inliers = self.ransac_inliers?;
        (self.descriptor_matches > 0).then(|| inliers as f32 / self.descriptor_matches as f32)
    }

    /// The first stage, in the check's order, whose threshold in `th` these
    /// counts fail, with the count reached there (0 for a stage that did
    /// not run; for [`LoopStage::Drift`], the correction in per cent of
    /// what drift explains; for [`LoopStage::Handover`], the gap in per
    /// cent of what a revisit explains); `None` when every stage passes. The only place
    /// that decides a candidate's verdict from its counts.
    pub fn first_failing(&self, th: &LoopThresholds) -> Option<(LoopStage, usize)> {
        if self.descriptor_matches < th.min_matches {
            return Some((LoopStage::DescriptorMatches, self.descriptor_matches));
        }
        let ransac = self.ransac_inliers.unwrap_or(0);
        let explained = self.ransac_inlier_ratio().unwrap_or(0.0);
        if ransac < th.min_ransac_inliers || explained < th.min_ransac_inlier_ratio {
            return Some((LoopStage::Ransac, ransac));
        }
        let stages = [
            (
                LoopStage::PoseOptimisation,
                self.optimised_inliers,
                th.min_optimised_inliers,
            ),
            (
                LoopStage::Projection,
                self.projection_matches,
                th.min_projection_matches,
            ),
            (
                LoopStage::Reprojection,
                self.reprojection_inliers,
                th.min_reprojection_inliers,
            ),
        ];
        let counted = stages.into_iter().find_map(|(stage, count, min)| {
            let count = count.unwrap_or(0);
            (count < min).then_some((stage, count))
        });
        let percent = |excess: f64| (100.0 * excess).round().min(1e9) as usize;
        counted
            .or_else(|| {
                let excess = self.drift?.excess(th);
                (excess > 1.0).then(|| (LoopStage::Drift, percent(excess)))
            })
            .or_else(|| {
                let excess = self.handover?.excess(th);
                (excess > 1.0).then(|| (LoopStage::Handover, percent(excess)))
            })
    }
}

/// One candidate's check as a run records it: every candidate the
/// database proposed, verified or not.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CandidateCheck {
    /// The keyframe that looked for a loop (or a merge).
    pub query: KeyFrameId,
    /// The candidate.
    pub candidate: KeyFrameId,
    /// Its global-descriptor similarity with the query.
    pub score: f32,
    /// What each stage counted.
    pub counts: LoopStageCounts,
    /// The stage that rejected it (`None`: it passed every geometric stage;
    /// confirmation comes after).
    pub rejected_at: Option<LoopStage>,
    /// The candidate camera's centre in the query camera's frame at the
    /// pose the check reached last (metres; `None` without a RANSAC pose):
    /// what a ground truth can judge the registration by.
    pub candidate_in_query: Option<[f64; 3]>,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn counts(m: usize, r: Option<usize>, o: usize, p: usize, f: usize) -> LoopStageCounts {
        LoopStageCounts {
            descriptor_matches: m,
            ransac_inliers: r,
            optimised_inliers: Some(o),
            projection_matches: Some(p),
            reprojection_inliers: Some(f),
            drift: None,
            handover: None,
        }
    }

    #[test]
    fn the_first_failing_stage_is_found_in_the_checks_order() {
        let th = LoopThresholds {
            min_ransac_inlier_ratio: 0.6,
            ..LoopThresholds::default()
        };
        assert_eq!(counts(100, Some(90), 90, 150, 120).first_failing(&th), None);
        // Each stage at one below its threshold, the later ones failing too.
        assert_eq!(
            counts(19, Some(0), 0, 0, 0).first_failing(&th),
            Some((LoopStage::DescriptorMatches, 19))
        );
        assert_eq!(
            counts(100, None, 0, 0, 0).first_failing(&th),
            Some((LoopStage::Ransac, 0))
        );
        assert_eq!(
            counts(100, Some(14), 90, 150, 120).first_failing(&th),
            Some((LoopStage::Ransac, 14))
        );
        // 59 of 100 matches explained: below the 0.6 ratio.
        assert_eq!(
            counts(100, Some(59), 90, 150, 120).first_failing(&th),
            Some((LoopStage::Ransac, 59))
        );
        assert_eq!(
            counts(100, Some(60), 19, 150, 120).first_failing(&th),
            Some((LoopStage::PoseOptimisation, 19))
        );
        assert_eq!(
            counts(100, Some(60), 20, 49, 120).first_failing(&th),
            Some((LoopStage::Projection, 49))
        );
        assert_eq!(
            counts(100, Some(60), 20, 50, 79).first_failing(&th),
            Some((LoopStage::Reprojection, 79))
        );
        let unrun = LoopStageCounts {
            reprojection_inliers: None,
            ..counts(100, Some(60), 20, 50, 0)
        };
        assert_eq!(unrun.first_failing(&th), Some((LoopStage::Reprojection, 0)));
        assert_eq!(LoopStageCounts::default().ransac_inlier_ratio(), None);
    }

    #[test]
    fn a_correction_beyond_drift_fails_last_and_only_then() {
        use super::super::drift::{LoopDrift, Travel};
        let th = LoopThresholds::default();
        let drift = |correction_m: f64| LoopDrift {
            correction_m,
            correction_deg: 1.0,
            travel: Travel {
                path_m: 100.0,
                turned_deg: 90.0,
                scene_depth_m: 10.0,
                metric: true,
            },
        };
        let allowed_m = th.max_drift_ratio * 100.0;
        let with = |d: LoopDrift, f: usize| LoopStageCounts {
            drift: Some(d),
            ..counts(100, Some(90), 90, 150, f)
        };
        assert_eq!(with(drift(0.9 * allowed_m), 120).first_failing(&th), None);
        assert_eq!(
            with(drift(2.0 * allowed_m), 120).first_failing(&th),
            Some((LoopStage::Drift, 200))
        );
        // A count that fails comes first.
        assert_eq!(
            with(drift(2.0 * allowed_m), 79).first_failing(&th),
            Some((LoopStage::Reprojection, 79))
        );
    }

    #[test]
    fn a_merge_too_far_from_the_handover_fails_last_and_only_then() {
        let th = LoopThresholds::default();
        let gap = |gap_m: f64| HandoverGap {
            gap_m,
            frames: 5,
            speed_m_per_frame: 1.0,
            drift_path_m: 0.0,
            scene_depth_m: 0.0,
        };
        let allowed_m = th.max_handover_speedup * 5.0;
        let with = |g: HandoverGap, f: usize| LoopStageCounts {
            handover: Some(g),
            ..counts(100, Some(90), 90, 150, f)
        };
        assert_eq!(with(gap(0.9 * allowed_m), 120).first_failing(&th), None);
        assert_eq!(
            with(gap(3.0 * allowed_m), 120).first_failing(&th),
            Some((LoopStage::Handover, 300))
        );
        assert_eq!(
            with(gap(3.0 * allowed_m), 79).first_failing(&th),
            Some((LoopStage::Reprojection, 79))
        );
    }
}
