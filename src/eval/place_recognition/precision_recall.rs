//! Precision and recall of a place-recognition acceptance rule. Each
//! verified candidate carries the rule's statistic (its score: inliers, an
//! inlier ratio, …) and its ground truth; a threshold accepts the
//! candidates scoring at least it.
//!
//! - **Precision** is over accepted candidates whose truth is known: the
//!   fraction that show the query's place. An accepted candidate whose
//!   views only partly overlap ([`CandidateTruth::Ambiguous`]) counts
//!   neither way, as in the usual loop-closure benchmarks.
//! - **Recall** is over revisiting queries (those with an earlier, searchable
//!   image of the same place): the fraction for which at least one accepted
//!   candidate shows that place. It counts what retrieval missed as well as
//!   what the rule refused.

use std::collections::BTreeSet;

use serde::{Deserialize, Serialize};

/// Views overlapping at least this much show the same place.
pub const SAME_PLACE_OVERLAP: f64 = 0.5;
/// Views overlapping less than this show different places.
pub const DIFFERENT_PLACE_OVERLAP: f64 = 0.1;

/// Whether a candidate truly shows the query's place.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CandidateTruth {
    /// The views overlap by at least [`SAME_PLACE_OVERLAP`].
    Same,
    /// The views overlap by less than [`DIFFERENT_PLACE_OVERLAP`].
    Different,
    /// In between: neither a hit nor a false match.
    Ambiguous,
}

impl CandidateTruth {
    /// The truth of a candidate whose view overlaps the query's by `overlap`.
    pub fn from_overlap(overlap: f64) -> Self {
        if overlap >= SAME_PLACE_OVERLAP {
            Self::Same
        } else if overlap < DIFFERENT_PLACE_OVERLAP {
            Self::Different
        } else {
            Self::Ambiguous
        }
    }
}

/// One verified candidate: its query, the rule's statistic and its truth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScoredCandidate {
    /// The query image (or keyframe) it was found for.
    pub query: usize,
    /// The acceptance rule's statistic; accepted when at least the threshold.
    pub score: f64,
    /// Whether it shows the query's place.
    pub truth: CandidateTruth,
}

/// The queries that revisit a place: those with at least one earlier,
/// searchable image showing it.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RevisitTruth {
    /// Their ids.
    pub queries: BTreeSet<usize>,
}

/// One point of a precision–recall curve.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PrPoint {
    /// Candidates scoring at least this are accepted.
    pub threshold: f64,
    /// Accepted candidates showing the query's place.
    pub true_accepted: usize,
    /// Accepted candidates showing another place.
    pub false_accepted: usize,
    /// `true / (true + false)`; 1 when none is accepted.
    pub precision: f64,
    /// Revisiting queries with an accepted true candidate, over all
    /// revisiting queries; `None` when there are none.
    pub recall: Option<f64>,
}

/// The precision and recall of accepting candidates scoring at least each
/// of `thresholds`.
pub fn precision_recall(
    candidates: &[ScoredCandidate],
    revisits: &RevisitTruth,
    thresholds: &[f64],
) -> Vec<PrPoint> {
    thresholds
        .iter()
        .map(|&threshold| {
            let accepted = candidates.iter().filter(|c| c.score >= threshold);
            let mut true_accepted = 0;
            let mut false_accepted = 0;
            let mut found = BTreeSet::new();
            for c in accepted {
                match c.truth {
                    CandidateTruth::Same => {
                        true_accepted += 1;
                        if revisits.queries.contains(&c.query) {
                            found.insert(c.query);
                        }
                    }
                    CandidateTruth::Different => false_accepted += 1,
                    CandidateTruth::Ambiguous => {}
                }
            }
            let judged = true_accepted + false_accepted;
            PrPoint {
                threshold,
                true_accepted,
                false_accepted,
                precision: if judged == 0 {
                    1.0
                } else {
                    true_accepted as f64 / judged as f64
                },
                recall: (!revisits.queries.is_empty())
                    .then(|| found.len() as f64 / revisits.queries.len() as f64),
            }
        })
        .collect()
}

/// The lowest threshold at which no accepted candidate shows another
/// place: just above the best-scoring false candidate (0 when there is
/// none). Every threshold at or above it has precision 1.
pub fn lowest_exact_threshold(candidates: &[ScoredCandidate]) -> f64 {
    candidates
        .iter()
        .filter(|c| c.truth == CandidateTruth::Different)
        .map(|c| c.score)
        .fold(None, |best: Option<f64>, s| {
            Some(best.map_or(s, |b| b.max(s)))
        })
        .map_or(0.0, next_up)
}

/// The smallest `f64` above `x` (for finite, non-negative `x`).
fn next_up(x: f64) -> f64 {
    if x.is_finite() && x >= 0.0 {
        f64::from_bits(x.to_bits() + 1)
    } else {
        x
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn candidate(query: usize, score: f64, truth: CandidateTruth) -> ScoredCandidate {
        ScoredCandidate {
            query,
            score,
            truth,
        }
    }

    /// Precision and recall counted one by one, for comparison.
    fn brute_force(
        candidates: &[ScoredCandidate],
        revisits: &RevisitTruth,
        threshold: f64,
    ) -> (f64, f64) {
        let accepted: Vec<_> = candidates.iter().filter(|c| c.score >= threshold).collect();
        let t = accepted
            .iter()
            .filter(|c| c.truth == CandidateTruth::Same)
            .count();
        let f = accepted
            .iter()
            .filter(|c| c.truth == CandidateTruth::Different)
            .count();
        let hit = revisits
            .queries
            .iter()
            .filter(|q| {
                accepted
                    .iter()
                    .any(|c| c.query == **q && c.truth == CandidateTruth::Same)
            })
            .count();
        let precision = if t + f == 0 {
            1.0
        } else {
            t as f64 / (t + f) as f64
        };
        (precision, hit as f64 / revisits.queries.len() as f64)
    }

    #[test]
    fn a_curve_matches_counting_by_hand() {
        use CandidateTruth::*;
        let candidates = [
            candidate(10, 100.0, Same),
            candidate(10, 40.0, Same),
            candidate(11, 30.0, Same),
            candidate(12, 45.0, Different),
            candidate(13, 20.0, Different),
            candidate(14, 60.0, Ambiguous),
            candidate(15, 25.0, Same),
        ];
        let revisits = RevisitTruth {
            queries: [10, 11, 15, 16].into_iter().collect(),
        };
        let thresholds = [0.0, 20.0, 25.0, 30.0, 45.0, 46.0, 101.0];
        let curve = precision_recall(&candidates, &revisits, &thresholds);
        for (point, &t) in curve.iter().zip(&thresholds) {
            let (p, r) = brute_force(&candidates, &revisits, t);
            assert!((point.precision - p).abs() < 1e-12, "threshold {t}");
            assert!((point.recall.unwrap() - r).abs() < 1e-12, "threshold {t}");
        }
        // Query 16 was never retrieved: recall stays below 1 at any threshold.
        assert_eq!(curve[0].recall, Some(0.75));
        // Above the false candidate at 45 every accepted one is true.
        assert_eq!(lowest_exact_threshold(&candidates), next_up(45.0));
        let exact = precision_recall(&candidates, &revisits, &[next_up(45.0)]);
        assert_eq!(exact[0].precision, 1.0);
        assert_eq!(exact[0].false_accepted, 0);
        assert_eq!(exact[0].recall, Some(0.25));
    }

    #[test]
    fn overlap_classes_have_a_gap_between_them() {
        assert_eq!(CandidateTruth::from_overlap(0.9), CandidateTruth::Same);
        assert_eq!(CandidateTruth::from_overlap(0.3), CandidateTruth::Ambiguous);
        assert_eq!(CandidateTruth::from_overlap(0.0), CandidateTruth::Different);
        let none = precision_recall(&[], &RevisitTruth::default(), &[1.0]);
        assert_eq!((none[0].precision, none[0].recall), (1.0, None));
    }
}
