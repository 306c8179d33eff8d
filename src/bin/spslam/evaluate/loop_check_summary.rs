//! The loop check's part of the summary: the loop and merge candidates of
//! every run that recorded its checks (`spslam run --record-loop-stages`),
//! each judged by its registration against the ground truth (right within
//! 1 m, wrong beyond 3 m: `run/candidate_truth.rs`), and for each threshold
//! of the check ([`LoopThresholds`]) the candidates that would pass the
//! geometric stages at values around the default, the others at theirs.
//! Passing the check is not yet a loop: ORB-SLAM3's confirmation by three
//! keyframes comes after, and the tables do not model it.

use std::fmt::Write as _;

use serde::Deserialize;
use spslam::eval::place_recognition::CandidateTruth;
use spslam::loop_closing::{LoopStageCounts, LoopThresholds};

use super::cases::Case;
use super::layout::SuiteLayout;
use super::record::CaseRecord;

/// What the summary reads of one recorded candidate.
#[derive(Debug, Clone, Copy, Deserialize)]
pub struct JudgedRecord {
    /// Input frame of the query keyframe.
    pub query_frame: usize,
    /// What each stage counted.
    pub counts: LoopStageCounts,
    /// Its registration's truth (`None`: not judged).
    pub truth: Option<CandidateTruth>,
}

#[derive(Debug, Deserialize)]
struct ReportCandidates {
    #[serde(default)]
    loop_candidates: Vec<JudgedRecord>,
}

/// One run that recorded its loop checks.
#[derive(Debug, Clone)]
pub struct LoopCheckRow {
    /// The case.
    pub case: String,
    /// Its candidates.
    pub candidates: Vec<JudgedRecord>,
    /// The commit and machine it ran on.
    pub record: CaseRecord,
}

/// The runs among `cases` whose report.json holds recorded loop checks.
pub fn collect(
    layout: &SuiteLayout,
    cases: &[&Case],
    definition: impl Fn(&Case) -> String,
) -> Vec<LoopCheckRow> {
    cases
        .iter()
        .filter_map(|case| {
            let record = CaseRecord::read(&layout.case_record(&case.name)).ok()?;
            if record.definition != definition(case) {
                return None;
            }
            let text = std::fs::read_to_string(layout.report(&case.name)).ok()?;
            let report: ReportCandidates = serde_json::from_str(&text).ok()?;
            (!report.loop_candidates.is_empty()).then(|| LoopCheckRow {
                case: case.name.clone(),
                candidates: report.loop_candidates,
                record,
            })
        })
        .collect()
}

/// A threshold of the loop check that the summary sweeps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LoopParameter {
    /// [`LoopThresholds::min_matches`].
    Matches,
    /// [`LoopThresholds::min_ransac_inliers`].
    RansacInliers,
    /// [`LoopThresholds::min_ransac_inlier_ratio`].
    RansacInlierRatio,
    /// [`LoopThresholds::min_optimised_inliers`].
    OptimisedInliers,
    /// [`LoopThresholds::min_projection_matches`].
    ProjectionMatches,
    /// [`LoopThresholds::min_reprojection_inliers`].
    ReprojectionInliers,
    /// [`LoopThresholds::max_drift_ratio`].
    DriftRatio,
}

impl LoopParameter {
    /// Every swept threshold, in the check's order.
    pub const ALL: [Self; 7] = [
        Self::Matches,
        Self::RansacInliers,
        Self::RansacInlierRatio,
        Self::OptimisedInliers,
        Self::ProjectionMatches,
        Self::ReprojectionInliers,
        Self::DriftRatio,
    ];

    /// Its field's name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Matches => "min_matches",
            Self::RansacInliers => "min_ransac_inliers",
            Self::RansacInlierRatio => "min_ransac_inlier_ratio",
            Self::OptimisedInliers => "min_optimised_inliers",
            Self::ProjectionMatches => "min_projection_matches",
            Self::ReprojectionInliers => "min_reprojection_inliers",
            Self::DriftRatio => "max_drift_ratio",
        }
    }

    /// The count threshold it names in `th` (`None` for the ratios).
    fn count_mut(self, th: &mut LoopThresholds) -> Option<&mut usize> {
        match self {
            Self::Matches => Some(&mut th.min_matches),
            Self::RansacInliers => Some(&mut th.min_ransac_inliers),
            Self::RansacInlierRatio | Self::DriftRatio => None,
            Self::OptimisedInliers => Some(&mut th.min_optimised_inliers),
            Self::ProjectionMatches => Some(&mut th.min_projection_matches),
            Self::ReprojectionInliers => Some(&mut th.min_reprojection_inliers),
        }
    }

    /// Its value in `th`.
    pub fn value(self, th: &LoopThresholds) -> f64 {
        let mut th = *th;
        match (self, self.count_mut(&mut th)) {
            (_, Some(count)) => *count as f64,
            (Self::DriftRatio, None) => th.max_drift_ratio,
            (_, None) => f64::from(th.min_ransac_inlier_ratio),
        }
    }

    /// `th` with this threshold at `value` (counts round up).
    pub fn with(self, mut th: LoopThresholds, value: f64) -> LoopThresholds {
        match (self, self.count_mut(&mut th)) {
            (_, Some(count)) => *count = value.max(0.0).ceil() as usize,
            (Self::DriftRatio, None) => th.max_drift_ratio = value,
            (_, None) => th.min_ransac_inlier_ratio = value as f32,
        }
        th
    }

    /// The values swept: fractions and multiples of the default.
    pub fn sweep(self, th: &LoopThresholds) -> Vec<f64> {
        let default = self.value(th);
        let mut values: Vec<f64> = if self == Self::RansacInlierRatio {
            vec![0.0, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9]
        } else if self == Self::DriftRatio {
            vec![0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.3, 0.5, 1.0, 1e6]
        } else {
            [0.25, 0.5, 0.75, 1.0, 1.25, 1.5, 2.0, 3.0]
                .iter()
                .map(|f| (f * default).round())
                .collect()
        };
        if !values.iter().any(|v| same_value(*v, default)) {
            values.push(default);
        }
        values.sort_by(f64::total_cmp);
        values.dedup();
        values
    }
}

/// Candidates that pass the geometric stages under `th`, by truth.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Passed {
    /// Registered right.
    pub right: usize,
    /// Registered wrong: would be false loops if confirmed.
    pub wrong: usize,
    /// Query keyframes with at least one right candidate passing.
    pub queries: usize,
}

/// What `candidates` give under `th`.
pub fn passed(candidates: &[JudgedRecord], th: &LoopThresholds) -> Passed {
    let mut out = Passed::default();
    let mut queries = std::collections::BTreeSet::new();
    for c in candidates
        .iter()
        .filter(|c| c.counts.first_failing(th).is_none())
    {
        match c.truth {
            Some(CandidateTruth::Same) => {
                out.right += 1;
                queries.insert(c.query_frame);
            }
            Some(CandidateTruth::Different) => out.wrong += 1,
            _ => {}
        }
    }
    out.queries = queries.len();
    out
}

/// The loop-check section as markdown (empty without rows).
pub fn markdown(rows: &[LoopCheckRow]) -> String {
    let mut md = String::new();
    if rows.is_empty() {
        return md;
    }
    let th = LoopThresholds::default();
    let _ = writeln!(
        md,
        "\n### The loop check's thresholds against the ground truth\n"
    );
    let _ = writeln!(
        md,
        "Every loop and merge candidate of the runs made with `--record-loop-stages`, checked through every stage, judged by where the check registered the candidate camera against the ground truth (right: within 1 m; wrong: beyond 3 m; between: not counted; monocular runs are not judged). \
         A candidate *passes* when every stage passes: the geometric ones in ORB-SLAM3's order, then the correction against the way travelled (for monocular runs its rotation only) (`max_drift_ratio`; 1000000 turns it off); a loop then still needs three confirming keyframes, which these tables do not model. \
         Cells: right + wrong candidates passing (query keyframes with a right one).\n"
    );
    let _ = writeln!(
        md,
        "| Case | Candidates | Right / wrong / between / not judged | Passing at the defaults: right + wrong | Commit | Machine |"
    );
    let _ = writeln!(md, "|---|---|---|---|---|---|");
    for row in rows {
        let count =
            |t: Option<CandidateTruth>| row.candidates.iter().filter(|c| c.truth == t).count();
        let p = passed(&row.candidates, &th);
        let _ = writeln!(
            md,
            "| {} | {} | {} / {} / {} / {} | {} + {} | {} | {} |",
            row.case,
            row.candidates.len(),
            count(Some(CandidateTruth::Same)),
            count(Some(CandidateTruth::Different)),
            count(Some(CandidateTruth::Ambiguous)),
            count(None),
            p.right,
            p.wrong,
            row.record.commit,
            row.record.machine
        );
    }
    let header: Vec<&str> = rows.iter().map(|r| r.case.as_str()).collect();
    for parameter in LoopParameter::ALL {
        let default = parameter.value(&th);
        let _ = writeln!(
            md,
            "\n`{}` (default {}), the other thresholds at their defaults:\n",
            parameter.name(),
            format_value(default)
        );
        let _ = writeln!(
            md,
            "| Value | {} | All: wrong passing |",
            header.join(" | ")
        );
        let _ = writeln!(md, "|---|{}---|", "---|".repeat(rows.len()));
        for value in parameter.sweep(&th) {
            let swept = parameter.with(th, value);
            let mut wrong = 0;
            let cells: Vec<String> = rows
                .iter()
                .map(|row| {
                    let p = passed(&row.candidates, &swept);
                    wrong += p.wrong;
                    format!("{} + {} ({})", p.right, p.wrong, p.queries)
                })
                .collect();
            let mark = if same_value(value, default) {
                " (default)"
            } else {
                ""
            };
            let _ = writeln!(
                md,
                "| {}{mark} | {} | {wrong} |",
                format_value(value),
                cells.join(" | ")
            );
        }
    }
    md
}

/// Equal up to an `f32` threshold's rounding.
fn same_value(a: f64, b: f64) -> bool {
    (a - b).abs() < 1e-6
}

fn format_value(v: f64) -> String {
    if v.fract() == 0.0 {
        format!("{v:.0}")
    } else {
        // Up to three decimals, trailing zeros cut (0.005, 0.75).
        let text = format!("{v:.3}");
        text.trim_end_matches('0').to_string()
    }
}

/// The loop-check rows for `summary.json`.
pub fn json(rows: &[LoopCheckRow]) -> serde_json::Value {
    let th = LoopThresholds::default();
    let cases: Vec<serde_json::Value> = rows
        .iter()
        .map(|row| {
            let sweeps: Vec<serde_json::Value> = LoopParameter::ALL
                .into_iter()
                .map(|parameter| {
                    let points: Vec<serde_json::Value> = parameter
                        .sweep(&th)
                        .into_iter()
                        .map(|value| {
                            let p = passed(&row.candidates, &parameter.with(th, value));
                            serde_json::json!({ "value": value, "right": p.right, "wrong": p.wrong, "queries": p.queries })
                        })
                        .collect();
                    serde_json::json!({ "threshold": parameter.name(), "points": points })
                })
                .collect();
            serde_json::json!({
                "case": row.case,
                "candidates": row.candidates.len(),
                "commit": row.record.commit,
                "machine": row.record.machine,
                "sweeps": sweeps,
            })
        })
        .collect();
    serde_json::Value::Array(cases)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn judged(
        query_frame: usize,
        counts: [usize; 5],
        truth: Option<CandidateTruth>,
    ) -> JudgedRecord {
        let [m, r, o, p, f] = counts;
        JudgedRecord {
            query_frame,
            counts: LoopStageCounts {
                descriptor_matches: m,
                ransac_inliers: Some(r),
                optimised_inliers: Some(o),
                projection_matches: Some(p),
                reprojection_inliers: Some(f),
                drift: None,
                handover: None,
            },
            truth,
        }
    }

    fn passing(right: usize, wrong: usize, queries: usize) -> Passed {
        Passed {
            right,
            wrong,
            queries,
        }
    }

    #[test]
    fn a_sweep_moves_one_threshold_and_counts_by_truth() {
        let right = Some(CandidateTruth::Same);
        let wrong = Some(CandidateTruth::Different);
        let candidates = [
            judged(10, [100, 90, 90, 150, 140], right),
            judged(10, [100, 90, 90, 150, 120], right),
            judged(20, [100, 90, 90, 150, 70], right),
            // A look-alike: many matches, half of them explained.
            judged(30, [100, 50, 50, 120, 95], wrong),
            judged(40, [10, 9, 9, 60, 60], None),
        ];
        let th = LoopThresholds::default();
        assert_eq!(passed(&candidates, &th), passing(2, 0, 1));
        let low = LoopParameter::ReprojectionInliers.with(th, 60.0);
        assert_eq!(passed(&candidates, &low), passing(3, 0, 2));
        let no_ratio = LoopParameter::RansacInlierRatio.with(th, 0.0);
        assert_eq!(passed(&candidates, &no_ratio), passing(2, 1, 1));
        // A look-alike that passes every count but moves the query 20 m
        // after 26 m of travel: the drift gate alone stops it.
        let mut far = judged(50, [100, 95, 95, 150, 120], wrong);
        far.counts.drift = Some(spslam::loop_closing::LoopDrift {
            correction_m: 20.0,
            correction_deg: 5.0,
            travel: spslam::loop_closing::Travel {
                path_m: 26.0,
                turned_deg: 90.0,
                scene_depth_m: 8.0,
                metric: true,
            },
        });
        let with_far = [candidates.as_slice(), &[far]].concat();
        assert_eq!(passed(&with_far, &th), passing(2, 0, 1));
        let no_gate = LoopParameter::DriftRatio.with(th, 1e6);
        assert_eq!(passed(&with_far, &no_gate), passing(2, 1, 1));
        let sweep = LoopParameter::ReprojectionInliers.sweep(&th);
        assert!(sweep.contains(&80.0) && sweep.contains(&20.0) && sweep.contains(&240.0));
        assert!(sweep.windows(2).all(|w| w[0] < w[1]));
        for p in LoopParameter::ALL {
            assert_eq!(
                p.value(&p.with(th, p.value(&th))),
                p.value(&th),
                "{}",
                p.name()
            );
        }
    }
}
