//! The place-recognition part of the summary: the precision–recall of each
//! acceptance rule of `spslam loops` over every `place` case, from their
//! `curves.json` files, per case and over all of them.

use std::fmt::Write as _;

use serde::Deserialize;
use spslam::eval::place_recognition::{
    lowest_exact_threshold, precision_recall, CandidateTruth, PrPoint, RevisitTruth,
    ScoredCandidate,
};

use super::cases::Case;
use super::layout::SuiteLayout;
use super::record::CaseRecord;
use super::summary::MissingRun;
use crate::loops::curves::{self, AcceptanceRule, CandidateRecord};

/// What the summary reads of a `curves.json`.
#[derive(Debug, Clone, Deserialize)]
pub struct PlaceResult {
    /// Frames read.
    pub images: usize,
    /// Queries with an earlier, searchable frame of the same place.
    pub revisiting_queries: Vec<usize>,
    /// Every verified candidate.
    pub candidates: Vec<CandidateRecord>,
}

/// One place case with its results.
#[derive(Debug, Clone)]
pub struct PlaceRow {
    /// The case.
    pub case: String,
    /// Its results.
    pub result: PlaceResult,
    /// The commit and machine it ran on.
    pub record: CaseRecord,
}

/// The place cases that have curves, and those that have none.
pub fn collect(
    layout: &SuiteLayout,
    cases: &[&Case],
    definition: impl Fn(&Case) -> String,
) -> (Vec<PlaceRow>, Vec<MissingRun>) {
    let mut rows = Vec::new();
    let mut missing = Vec::new();
    for case in cases {
        let miss = |why: String| MissingRun {
            case: case.name.clone(),
            why,
        };
        let Ok(record) = CaseRecord::read(&layout.case_record(&case.name)) else {
            missing.push(miss("not run".into()));
            continue;
        };
        if record.definition != definition(case) {
            missing.push(miss(
                "its definition changed since it ran (run it again)".into(),
            ));
            continue;
        }
        let result = std::fs::read_to_string(layout.curves(&case.name))
            .ok()
            .and_then(|t| serde_json::from_str::<PlaceResult>(&t).ok());
        match result {
            Some(result) => rows.push(PlaceRow {
                case: case.name.clone(),
                result,
                record,
            }),
            None => missing.push(miss(format!(
                "spslam loops ended with {} and wrote no curves; see {}",
                record
                    .exit_code
                    .map_or("a signal".into(), |c| format!("exit code {c}")),
                layout.log(&case.name).display()
            ))),
        }
    }
    (rows, missing)
}

/// The candidates of `row` scored by `rule`, with their truth.
fn scored(row: &PlaceRow, rule: AcceptanceRule) -> Vec<ScoredCandidate> {
    curves::scored(&row.result.candidates, rule)
}

fn revisits(row: &PlaceRow) -> RevisitTruth {
    RevisitTruth {
        queries: row.result.revisiting_queries.iter().copied().collect(),
    }
}

fn cell(p: &PrPoint) -> String {
    let recall = p.recall.map_or("–".to_string(), |r| format!("{r:.2}"));
    format!(
        "{:.2} / {recall} ({}+{})",
        p.precision, p.true_accepted, p.false_accepted
    )
}

/// The place-recognition section as markdown.
pub fn markdown(rows: &[PlaceRow], missing: &[MissingRun]) -> String {
    let mut md = String::new();
    if rows.is_empty() && missing.is_empty() {
        return md;
    }
    let _ = writeln!(
        md,
        "\n### Place recognition: acceptance rules against the ground truth\n"
    );
    let _ = writeln!(
        md,
        "`spslam loops --dataset` over each sequence: every candidate the database proposes is verified (fundamental-matrix RANSAC) and judged by the ground truth (`src/eval/place_recognition`: the share of the query's view the candidate sees at a similar scale and angle; ≥ 0.5 the same place, < 0.1 another, between: not counted). \
         A query *revisits* when an earlier searchable image shows its place and the camera looked away in between. \
         Cells: precision / recall (true + false accepted); recall is over revisiting queries and counts what retrieval missed too.\n"
    );
    let _ = writeln!(md, "| Case | Images | Revisiting queries | Candidates (same / other / between) | Commit | Machine |");
    let _ = writeln!(md, "|---|---|---|---|---|---|");
    for row in rows {
        let count = |t: CandidateTruth| {
            row.result
                .candidates
                .iter()
                .filter(|c| c.truth == Some(t))
                .count()
        };
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} / {} / {} | {} | {} |",
            row.case,
            row.result.images,
            row.result.revisiting_queries.len(),
            count(CandidateTruth::Same),
            count(CandidateTruth::Different),
            count(CandidateTruth::Ambiguous),
            row.record.commit,
            row.record.machine
        );
    }
    for rule in AcceptanceRule::ALL {
        let _ = writeln!(md, "\nAcceptance by {}:\n", rule.label());
        let header: Vec<String> = rows.iter().map(|r| r.case.clone()).collect();
        let _ = writeln!(
            md,
            "| Threshold | {} | All: false accepted |",
            header.join(" | ")
        );
        let _ = writeln!(md, "|---|{}---|", "---|".repeat(rows.len()));
        let all: Vec<ScoredCandidate> = rows.iter().flat_map(|r| scored(r, rule)).collect();
        let exact = lowest_exact_threshold(&all);
        let mut thresholds = rule.thresholds();
        thresholds.push(exact);
        thresholds.sort_by(f64::total_cmp);
        thresholds.dedup();
        for t in thresholds {
            let mut cells = Vec::new();
            let mut false_accepted = 0;
            for row in rows {
                let p = precision_recall(&scored(row, rule), &revisits(row), &[t])[0];
                false_accepted += p.false_accepted;
                cells.push(cell(&p));
            }
            let mark = if t == exact {
                " (lowest with none false)"
            } else {
                ""
            };
            let _ = writeln!(
                md,
                "| {t:.3}{mark} | {} | {false_accepted} |",
                cells.join(" | ")
            );
        }
    }
    if !missing.is_empty() {
        let _ = writeln!(md, "\nPlace cases without curves:\n");
        for m in missing {
            let _ = writeln!(md, "- {}: {}", m.case, m.why);
        }
    }
    md
}

/// The place cases for `summary.json`: per case, its counts and each
/// rule's curve.
pub fn json(rows: &[PlaceRow]) -> serde_json::Value {
    let cases: Vec<serde_json::Value> = rows
        .iter()
        .map(|row| {
            let curves: Vec<serde_json::Value> = AcceptanceRule::ALL
                .into_iter()
                .map(|rule| {
                    let points =
                        precision_recall(&scored(row, rule), &revisits(row), &rule.thresholds());
                    serde_json::json!({ "rule": rule, "label": rule.label(), "points": points })
                })
                .collect();
            serde_json::json!({
                "case": row.case,
                "images": row.result.images,
                "revisiting_queries": row.result.revisiting_queries.len(),
                "candidates": row.result.candidates.len(),
                "commit": row.record.commit,
                "machine": row.record.machine,
                "curves": curves,
            })
        })
        .collect();
    serde_json::Value::Array(cases)
}
