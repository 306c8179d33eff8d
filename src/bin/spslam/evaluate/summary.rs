//! The suite's summary: one row per run from its report.json, a table per
//! group with the extractors side by side and which one wins, as markdown.

use std::collections::BTreeSet;
use std::fmt::Write as _;

use serde::Serialize;
use serde_json::Value;
use spslam::eval::{write_grouped_bar_plot, BarSeries};

use super::cases::Case;
use super::layout::SuiteLayout;
use super::record::CaseRecord;

/// What the summary shows of one run.
#[derive(Debug, Clone, Serialize)]
pub struct RunRow {
    /// The case.
    pub case: String,
    /// Its group.
    pub group: String,
    /// `ORB`, `SuperPoint` or `SuperPoint + ANMS`.
    pub extractor: String,
    /// `mono`, `stereo` or `rgbd`.
    pub sensor: String,
    /// Frames requested.
    pub frames: u64,
    /// Frames tracked.
    pub tracked: u64,
    /// Relocalisations.
    pub relocalisations: u64,
    /// Maps in the atlas at the end.
    pub maps: u64,
    /// Keyframes inserted.
    pub keyframes: u64,
    /// ATE RMSE, m: SE(3)-aligned, Sim(3)-aligned for monocular runs.
    pub ate_m: Option<f64>,
    /// `SE3` or `Sim3`.
    pub alignment: &'static str,
    /// Length of the ground-truth path, m.
    pub path_m: Option<f64>,
    /// Final-position drift, % of the path.
    pub drift_percent: Option<f64>,
    /// Wall time per frame, ms.
    pub ms_per_frame: f64,
    /// Loops closed.
    pub loops: u64,
    /// Maps merged.
    pub merges: u64,
    /// Loops and merges that are wrong (over 10 m apart in the ground
    /// truth and a final relative pose over 1 m from the truth's); None
    /// without ground truth.
    pub false_links: Option<u64>,
    /// Whether every frame was processed.
    pub complete: bool,
    /// The commit and machine of the run.
    pub commit: String,
    /// The machine.
    pub machine: String,
}

/// A case that has no usable report.
#[derive(Debug, Clone, Serialize)]
pub struct MissingRun {
    /// The case.
    pub case: String,
    /// Why: not run, failed (exit code), unreadable report.
    pub why: String,
}

/// The rows of the runs that have a report, and the cases that have none.
pub fn collect(
    layout: &SuiteLayout,
    cases: &[&Case],
    definition: impl Fn(&Case) -> String,
) -> (Vec<RunRow>, Vec<MissingRun>) {
    let mut rows = Vec::new();
    let mut missing = Vec::new();
    for case in cases {
        let record = CaseRecord::read(&layout.case_record(&case.name)).ok();
        if let Some(r) = &record {
            if r.definition != definition(case) {
                missing.push(MissingRun {
                    case: case.name.clone(),
                    why: "its definition changed since it ran (run it again)".into(),
                });
                continue;
            }
        }
        let report = std::fs::read_to_string(layout.report(&case.name))
            .ok()
            .and_then(|t| serde_json::from_str::<Value>(&t).ok());
        match (report, record) {
            (Some(report), Some(record)) => match row_of(case, &report, &record) {
                Some(row) => rows.push(row),
                None => missing.push(MissingRun {
                    case: case.name.clone(),
                    why: "its report.json has no summary".into(),
                }),
            },
            (_, record) => missing.push(MissingRun {
                case: case.name.clone(),
                why: match record {
                    None => "not run".into(),
                    Some(r) => format!(
                        "spslam run ended with {} and wrote no report; see {}",
                        r.exit_code
                            .map_or("a signal".into(), |c| format!("exit code {c}")),
                        layout.log(&case.name).display()
                    ),
                },
            }),
        }
    }
    (rows, missing)
}

/// The extractor as the tables name it, with the SuperPoint model when the
/// run named one (`SuperPoint + ANMS (photo)`).
fn extractor_label(report: &Value) -> String {
    // `orb`, `superpoint` or `superpoint+anms-<method>`.
    let extractor = report["extractor"].as_str().unwrap_or("?");
    let base = if extractor == "orb" {
        return "ORB".into();
    } else if extractor.starts_with("superpoint+anms") {
        "SuperPoint + ANMS"
    } else if extractor.starts_with("superpoint") {
        "SuperPoint"
    } else {
        return extractor.into();
    };
    // `SuperPoint.model`: a name (`photo`) or a file, named by its file name.
    match report["settings"]["extractor"]["model"].as_str() {
        Some(model) => {
            let name = std::path::Path::new(model)
                .file_name()
                .map_or_else(|| model.to_string(), |n| n.to_string_lossy().into_owned());
            format!("{base} ({name})")
        }
        None => base.into(),
    }
}

fn row_of(case: &Case, report: &Value, record: &CaseRecord) -> Option<RunRow> {
    let summary = report.get("summary").filter(|s| !s.is_null())?;
    let count = |v: &Value| v.as_u64().unwrap_or(0);
    let sensor = report["sensor"].as_str().unwrap_or("?").to_string();
    let mono = sensor == "mono";
    let ate = &report["evaluation"]["ate"];
    let ate_m = if mono {
        ate["sim3_rmse"].as_f64()
    } else {
        ate["se3_rmse"].as_f64()
    };
    Some(RunRow {
        case: case.name.clone(),
        group: case.group.clone(),
        extractor: extractor_label(report),
        sensor,
        frames: count(&report["frames_total"]),
        tracked: count(&summary["tracked"]),
        relocalisations: count(&summary["relocalisations"]),
        maps: summary["maps"].as_array().map_or(0, |m| m.len() as u64),
        keyframes: count(&summary["keyframes_inserted"]),
        ate_m,
        alignment: if mono { "Sim3" } else { "SE3" },
        path_m: report["evaluation"]["path_length_m"].as_f64(),
        drift_percent: report["drift"]["percent"].as_f64(),
        ms_per_frame: report["wall_ms_per_frame"].as_f64().unwrap_or(f64::NAN),
        loops: report["loops"].as_array().map_or(0, |l| l.len() as u64),
        merges: report["merges"].as_array().map_or(0, |l| l.len() as u64),
        false_links: report["links_ground_truth"].as_array().map(|links| {
            links
                .iter()
                .filter(|l| {
                    // Reports written before `correct` existed judged by distance.
                    let correct = l["correct"].as_bool().or(l["same_place"].as_bool());
                    correct == Some(false)
                })
                .count() as u64
        }),
        complete: report["complete"].as_bool().unwrap_or(false),
        commit: record.commit.clone(),
        machine: record.machine.clone(),
    })
}

/// The extractors in the order of the tables' columns.
const EXTRACTORS: [&str; 3] = ["ORB", "SuperPoint", "SuperPoint + ANMS"];

/// Better run first: fewer false loops or merges, more frames tracked,
/// then the lower ATE.
fn better(a: &RunRow, b: &RunRow) -> std::cmp::Ordering {
    let false_links = |r: &RunRow| r.false_links.unwrap_or(0);
    let ate = |r: &RunRow| error_of(r).map_or(f64::INFINITY, |(e, _)| e);
    false_links(a)
        .cmp(&false_links(b))
        .then(b.tracked.cmp(&a.tracked))
        .then(ate(a).total_cmp(&ate(b)))
}

/// The error a run is judged by: the ATE, or the final-position drift (%)
/// where the path cannot be aligned (a straight road), with its name.
fn error_of(r: &RunRow) -> Option<(f64, &'static str)> {
    match (r.ate_m, r.drift_percent) {
        (Some(ate), _) => Some((ate, "ATE")),
        (None, Some(drift)) => Some((drift, "drift")),
        (None, None) => None,
    }
}

/// Who wins a group and by how much, in words. Runs are named by their
/// extractor, or by their case where a group holds several runs of one
/// extractor (a parameter sweep).
pub fn verdict(rows: &[&RunRow]) -> String {
    let mut sorted: Vec<&RunRow> = rows.to_vec();
    sorted.sort_by(|a, b| better(a, b));
    let [best, runner_up, ..] = sorted.as_slice() else {
        return "one extractor only".into();
    };
    let sweep = |r: &RunRow| rows.iter().filter(|o| o.extractor == r.extractor).count() > 1;
    let named = |r: &RunRow| -> String {
        if sweep(r) {
            r.case.clone()
        } else {
            r.extractor.clone()
        }
    };
    let (best_name, runner_up_name) = (named(best), named(runner_up));
    let false_links = |r: &RunRow| r.false_links.unwrap_or(0);
    if false_links(best) != false_links(runner_up) {
        return format!(
            "{} ({} made {} false loop or merge)",
            best_name,
            runner_up_name,
            false_links(runner_up) - false_links(best)
        );
    }
    if best.tracked != runner_up.tracked {
        return format!(
            "{} (tracks {} more frames than {})",
            best_name,
            best.tracked - runner_up.tracked,
            runner_up_name
        );
    }
    match (best.ate_m, runner_up.ate_m) {
        (Some(a), Some(b)) if b > 0.0 => {
            let percent = 100.0 * (b - a) / b;
            if percent < 5.0 {
                format!(
                    "tie: {} and {} within 5 % ({percent:.1} %)",
                    best_name, runner_up_name
                )
            } else {
                format!(
                    "{} ({percent:.0} % lower ATE than {})",
                    best_name, runner_up_name
                )
            }
        }
        _ => "no ATE to compare".into(),
    }
}

/// One extractor's cell in a group's row: its run, or the best of its runs
/// (named) where the group holds several.
fn cell(in_group: &[&RunRow], extractor: &str) -> String {
    let mut runs: Vec<&RunRow> = in_group
        .iter()
        .copied()
        .filter(|r| r.extractor == extractor)
        .collect();
    runs.sort_by(|a, b| better(a, b));
    let Some(r) = runs.first() else {
        return "–".into();
    };
    let error = match error_of(r) {
        Some((ate, "ATE")) => format!("{ate:.4}"),
        Some((drift, _)) => format!("drift {drift:.2} %"),
        None => "n/a".into(),
    };
    let of = if runs.len() > 1 {
        format!("; best of {} runs: {}", runs.len(), r.case)
    } else {
        String::new()
    };
    format!(
        "{error} ({}/{}, {} KF{of})",
        r.tracked, r.frames, r.keyframes
    )
}

/// Distinct values of one field, joined.
fn distinct(rows: &[RunRow], field: impl Fn(&RunRow) -> &str) -> String {
    let set: BTreeSet<&str> = rows.iter().map(field).collect();
    set.into_iter().collect::<Vec<_>>().join("; ")
}

/// The summary as markdown: provenance, a table per group, every run.
pub fn markdown(rows: &[RunRow], missing: &[MissingRun], set: &str) -> String {
    let mut md = String::new();
    let _ = writeln!(
        md,
        "Generated by `spslam evaluate` from {} run reports (set `{set}`); commit {}; machine: {}.\n",
        rows.len(),
        distinct(rows, |r| &r.commit),
        distinct(rows, |r| &r.machine),
    );
    let _ = writeln!(
        md,
        "Cells: ATE RMSE in m (SE3-aligned; Sim3 for monocular runs; the final-position drift where a straight path cannot be aligned) (tracked/frames, keyframes). \
         The winner makes no false loop or merge, then tracks the most frames, then has the lowest ATE; under 5 % apart is a tie. \
         False links: loops and merges joining frames over 10 m apart in the ground truth whose final relative pose is over 1 m from the truth's (a monocular run's brought to metres by its path length over the 10 rows either side of each frame).\n"
    );
    let _ = writeln!(
        md,
        "| Group | ORB | SuperPoint | SuperPoint + ANMS | Winner |"
    );
    let _ = writeln!(md, "|---|---|---|---|---|");
    for group in &group_order(rows) {
        let in_group: Vec<&RunRow> = rows.iter().filter(|r| r.group == *group).collect();
        let _ = writeln!(
            md,
            "| {group} | {} | {} | {} | {} |",
            cell(&in_group, EXTRACTORS[0]),
            cell(&in_group, EXTRACTORS[1]),
            cell(&in_group, EXTRACTORS[2]),
            verdict(&in_group)
        );
    }
    let _ = writeln!(md, "\nEvery run:\n");
    let _ = writeln!(
        md,
        "| Case | Sensor | Extractor | Tracked | Relocalised | Maps | Keyframes | ATE (m) | Drift | ms/frame | Loops | Merges | False links |"
    );
    let _ = writeln!(md, "|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for r in rows {
        let ate = r
            .ate_m
            .map_or("n/a".into(), |a| format!("{a:.4} {}", r.alignment));
        let drift = r.drift_percent.map_or("–".into(), |d| format!("{d:.2} %"));
        let incomplete = if r.complete { "" } else { " (incomplete)" };
        let false_links = r.false_links.map_or("–".into(), |n| n.to_string());
        let _ = writeln!(
            md,
            "| {}{incomplete} | {} | {} | {}/{} | {} | {} | {} | {ate} | {drift} | {:.0} | {} | {} | {false_links} |",
            r.case, r.sensor, r.extractor, r.tracked, r.frames, r.relocalisations, r.maps,
            r.keyframes, r.ms_per_frame, r.loops, r.merges
        );
    }
    if !missing.is_empty() {
        let _ = writeln!(md, "\nCases without a report:\n");
        for m in missing {
            let _ = writeln!(md, "- {}: {}", m.case, m.why);
        }
    }
    md
}

/// Writes the ATE of every run as % of its path, a cluster per group and
/// a bar per extractor.
pub fn write_plot(rows: &[RunRow], path: &std::path::Path) -> spslam::eval::Result<()> {
    let groups = group_order(rows);
    let series: Vec<BarSeries> = EXTRACTORS
        .iter()
        .map(|name| BarSeries {
            name: (*name).to_string(),
            values: groups
                .iter()
                .map(|g| {
                    let r = rows
                        .iter()
                        .find(|r| &r.group == g && r.extractor == *name)?;
                    Some(100.0 * r.ate_m? / r.path_m.filter(|p| *p > 0.0)?)
                })
                .collect(),
        })
        .collect();
    write_grouped_bar_plot(
        path,
        "ATE per group and extractor (SE3; Sim3 for monocular)",
        "ATE RMSE, % of the path length",
        &groups,
        &series,
    )
}

/// The groups in the order their first run appears.
fn group_order(rows: &[RunRow]) -> Vec<String> {
    let mut groups: Vec<String> = Vec::new();
    for r in rows {
        if !groups.contains(&r.group) {
            groups.push(r.group.clone());
        }
    }
    groups
}

/// The markers of the standard set's generated block in a document.
pub const BEGIN_MARKER: &str = "<!-- spslam evaluate: begin -->";
/// See [`BEGIN_MARKER`].
pub const END_MARKER: &str = "<!-- spslam evaluate: end -->";

/// The begin and end markers of a set's generated block: [`BEGIN_MARKER`]
/// and [`END_MARKER`] for the standard set, `<!-- spslam evaluate SET:
/// begin -->` and `... end -->` for another, so that one document can hold
/// several sets' summaries.
pub fn markers(set: &str) -> (String, String) {
    if set == "standard" {
        (BEGIN_MARKER.into(), END_MARKER.into())
    } else {
        (
            format!("<!-- spslam evaluate {set}: begin -->"),
            format!("<!-- spslam evaluate {set}: end -->"),
        )
    }
}

/// `document` with the lines between the `begin` and `end` marker lines
/// replaced by `block`, or None when the markers are not on lines of their
/// own, in order.
pub fn replace_block_between(
    document: &str,
    block: &str,
    begin: &str,
    end: &str,
) -> Option<String> {
    let line_at = |marker: &str, from: usize| {
        let mut offset = from;
        document[from..].split_inclusive('\n').find_map(|line| {
            let start = offset;
            offset += line.len();
            (line.trim_end() == marker).then_some((start, offset))
        })
    };
    let (_, after_begin) = line_at(begin, 0)?;
    let (end, _) = line_at(end, after_begin)?;
    Some(format!(
        "{}{}{}",
        &document[..after_begin],
        block,
        &document[end..]
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn replace_block(document: &str, block: &str) -> Option<String> {
        replace_block_between(document, block, BEGIN_MARKER, END_MARKER)
    }

    #[test]
    fn each_set_has_its_own_markers() {
        assert_eq!(
            markers("standard"),
            (BEGIN_MARKER.into(), END_MARKER.into())
        );
        let (begin, end) = markers("models");
        let doc = format!("{BEGIN_MARKER}\nkept\n{END_MARKER}\n{begin}\nold\n{end}\n");
        let new = replace_block_between(&doc, "new\n", &begin, &end).expect("markers");
        assert_eq!(
            new,
            format!("{BEGIN_MARKER}\nkept\n{END_MARKER}\n{begin}\nnew\n{end}\n")
        );
    }

    fn row(extractor: &str, tracked: u64, ate: f64) -> RunRow {
        RunRow {
            case: format!("c_{extractor}"),
            group: "g".into(),
            extractor: extractor.into(),
            sensor: "stereo".into(),
            frames: 100,
            tracked,
            relocalisations: 0,
            maps: 1,
            keyframes: 10,
            ate_m: Some(ate),
            alignment: "SE3",
            path_m: Some(100.0),
            drift_percent: None,
            ms_per_frame: 50.0,
            loops: 0,
            merges: 0,
            false_links: Some(0),
            complete: true,
            commit: "abc".into(),
            machine: "m".into(),
        }
    }

    #[test]
    fn the_verdict_prefers_tracked_frames_then_ate() {
        let orb = row("ORB", 100, 0.062);
        let sp = row("SuperPoint + ANMS", 100, 0.045);
        assert_eq!(
            verdict(&[&orb, &sp]),
            "SuperPoint + ANMS (27 % lower ATE than ORB)"
        );
        let lost = row("SuperPoint + ANMS", 97, 0.01);
        assert_eq!(
            verdict(&[&orb, &lost]),
            "ORB (tracks 3 more frames than SuperPoint + ANMS)"
        );
        let close = row("SuperPoint", 100, 0.060);
        assert!(verdict(&[&orb, &close]).starts_with("tie"));
        let mut wrong = row("ORB", 100, 0.01);
        wrong.false_links = Some(1);
        assert_eq!(
            verdict(&[&wrong, &sp]),
            "SuperPoint + ANMS (ORB made 1 false loop or merge)"
        );
    }

    #[test]
    fn a_sweep_names_its_runs_by_case_and_its_cell_shows_the_best() {
        let mut off = row("SuperPoint + ANMS", 100, 1.1434);
        off.case = "lowlight_share0".into();
        let mut on = row("SuperPoint + ANMS", 100, 0.1979);
        on.case = "lowlight_share3".into();
        let orb = row("ORB", 100, 0.276);
        assert_eq!(
            verdict(&[&off, &on, &orb]),
            "lowlight_share3 (28 % lower ATE than ORB)"
        );
        assert_eq!(
            verdict(&[&off, &on]),
            "lowlight_share3 (83 % lower ATE than lowlight_share0)"
        );
        assert_eq!(
            cell(&[&off, &on, &orb], "SuperPoint + ANMS"),
            "0.1979 (100/100, 10 KF; best of 2 runs: lowlight_share3)"
        );
        assert_eq!(cell(&[&off, &on, &orb], "ORB"), "0.2760 (100/100, 10 KF)");
        assert_eq!(cell(&[&orb], "SuperPoint"), "–");
    }

    #[test]
    fn the_block_between_the_markers_is_replaced_and_the_rest_kept() {
        let doc = format!("intro\n{BEGIN_MARKER}\nold\n{END_MARKER}\nafter\n");
        let new = replace_block(&doc, "new table\n").expect("markers");
        assert_eq!(
            new,
            format!("intro\n{BEGIN_MARKER}\nnew table\n{END_MARKER}\nafter\n")
        );
        assert!(replace_block("no markers", "x").is_none());
        assert!(replace_block(&format!("see `{BEGIN_MARKER}` and `{END_MARKER}`"), "x").is_none());
        assert!(replace_block(&format!("{END_MARKER}{BEGIN_MARKER}"), "x").is_none());
    }
}
