//! Precision–recall curves of `spslam loops --dataset`: every verified
//! candidate with its ground truth, scored by each acceptance rule, and the
//! curves written as JSON and printed as tables.

use std::path::Path;

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use spslam::eval::place_recognition::{
    lowest_exact_threshold, precision_recall, CandidateTruth, PrPoint, RevisitTruth,
    ScoredCandidate,
};

/// A verified candidate and what every acceptance rule looks at.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CandidateRecord {
    /// The query image (index in name or frame order).
    pub query: usize,
    /// The candidate image.
    pub candidate: usize,
    /// The database's score.
    pub score: f32,
    /// Putative matches.
    pub matches: usize,
    /// Fundamental-matrix inliers.
    pub inliers: usize,
    /// Keypoints of the query image.
    pub query_keypoints: usize,
    /// Keypoints of the candidate image.
    pub candidate_keypoints: usize,
    /// How much of the query's view the candidate sees (ground truth).
    pub overlap: Option<f64>,
    /// What that overlap makes of it.
    pub truth: Option<CandidateTruth>,
}

/// An acceptance rule: a statistic of a verified candidate, accepted at or
/// above a threshold.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum AcceptanceRule {
    /// The inlier count (`--min-inliers`).
    Inliers,
    /// Inliers over putative matches, for candidates with at least
    /// `floor` inliers (0 below it).
    InlierRatio {
        /// The inliers a candidate needs before its ratio counts.
        floor: usize,
    },
    /// Inliers over the smaller keypoint count of the two images.
    InliersPerKeypoint,
}

impl AcceptanceRule {
    /// The rules whose curves are printed.
    pub const ALL: [Self; 4] = [
        Self::Inliers,
        Self::InlierRatio { floor: 12 },
        Self::InlierRatio { floor: 20 },
        Self::InliersPerKeypoint,
    ];

    /// The rule's statistic for `c`.
    pub fn statistic(self, c: &CandidateRecord) -> f64 {
        match self {
            Self::Inliers => c.inliers as f64,
            Self::InlierRatio { floor } => {
                if c.inliers < floor || c.matches == 0 {
                    0.0
                } else {
                    c.inliers as f64 / c.matches as f64
                }
            }
            Self::InliersPerKeypoint => {
                let k = c.query_keypoints.min(c.candidate_keypoints);
                if k == 0 {
                    0.0
                } else {
                    c.inliers as f64 / k as f64
                }
            }
        }
    }

    /// The thresholds at which the printed table samples the curve.
    pub fn thresholds(self) -> Vec<f64> {
        match self {
            Self::Inliers => [8, 10, 12, 15, 20, 25, 30, 40, 50, 60, 80, 100]
                .into_iter()
                .map(f64::from)
                .collect(),
            Self::InlierRatio { .. } => (1..=9).map(|k| f64::from(k) / 10.0).collect(),
            Self::InliersPerKeypoint => [0.01, 0.015, 0.02, 0.03, 0.04, 0.05, 0.06, 0.08, 0.1]
                .into_iter()
                .collect(),
        }
    }

    /// A label for tables.
    pub fn label(self) -> String {
        match self {
            Self::Inliers => "inliers".into(),
            Self::InlierRatio { floor } => format!("inliers / matches (with >= {floor} inliers)"),
            Self::InliersPerKeypoint => "inliers / keypoints".into(),
        }
    }
}

/// One rule's curve.
#[derive(Debug, Clone, Serialize)]
pub struct RuleCurve {
    /// The rule.
    pub rule: AcceptanceRule,
    /// Its label.
    pub label: String,
    /// The lowest threshold with no false match accepted.
    pub lowest_exact_threshold: f64,
    /// Precision and recall at that threshold.
    pub at_lowest_exact: PrPoint,
    /// The curve at the table's thresholds.
    pub points: Vec<PrPoint>,
}

/// The JSON file of `--curves`.
#[derive(Debug, Clone, Serialize)]
pub struct CurvesReport {
    /// The dataset.
    pub dataset: String,
    /// Frames read.
    pub images: usize,
    /// The queries with an earlier, searchable frame of the same place.
    pub revisiting_queries: Vec<usize>,
    /// Every verified candidate.
    pub candidates: Vec<CandidateRecord>,
    /// One curve per rule.
    pub curves: Vec<RuleCurve>,
}

/// The judged candidates scored by `rule` (those without a truth left out).
pub fn scored(candidates: &[CandidateRecord], rule: AcceptanceRule) -> Vec<ScoredCandidate> {
    candidates
        .iter()
        .filter_map(|c| {
            Some(ScoredCandidate {
                query: c.query,
                score: rule.statistic(c),
                truth: c.truth?,
            })
        })
        .collect()
}

/// The curves of every rule over `candidates`.
pub fn curves(candidates: &[CandidateRecord], revisits: &RevisitTruth) -> Vec<RuleCurve> {
    AcceptanceRule::ALL
        .into_iter()
        .map(|rule| {
            let scored = scored(candidates, rule);
            let lowest = lowest_exact_threshold(&scored);
            let at_lowest = precision_recall(&scored, revisits, &[lowest])[0];
            RuleCurve {
                rule,
                label: rule.label(),
                lowest_exact_threshold: lowest,
                at_lowest_exact: at_lowest,
                points: precision_recall(&scored, revisits, &rule.thresholds()),
            }
        })
        .collect()
}

/// Prints every curve as a table.
pub fn print_curves(report: &CurvesReport) {
    println!(
        "\nGround truth: {} of {} images revisit a place seen earlier (outside the excluded recent and covisible images); {} candidates judged",
        report.revisiting_queries.len(),
        report.images,
        report.candidates.iter().filter(|c| c.truth.is_some()).count()
    );
    for curve in &report.curves {
        println!("\nacceptance: {}", curve.label);
        println!(
            "{:>10} {:>6} {:>6} {:>10} {:>8}",
            "threshold", "true", "false", "precision", "recall"
        );
        let row = |p: &PrPoint| {
            println!(
                "{:>10.3} {:>6} {:>6} {:>10.3} {:>8}",
                p.threshold,
                p.true_accepted,
                p.false_accepted,
                p.precision,
                p.recall.map_or("-".to_string(), |r| format!("{r:.3}"))
            )
        };
        curve.points.iter().for_each(row);
        print!("lowest threshold with no false match: ");
        row(&curve.at_lowest_exact);
    }
}

/// Writes the report as JSON.
pub fn write_curves(path: &Path, report: &CurvesReport) -> Result<()> {
    let text = serde_json::to_string_pretty(report)?;
    std::fs::write(path, text + "\n").with_context(|| format!("cannot write {}", path.display()))
}
