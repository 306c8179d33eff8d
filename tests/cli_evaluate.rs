//! `spslam evaluate`, the evaluation suite: the quick set of the shipped
//! case list (`suite/cases.txt`) runs to the end and its summary is built
//! from the runs' reports; finished cases are not re-run, a changed case
//! is; `--list`'s commands run as written; a failed case is reported and
//! listed; `--update-doc` replaces only the generated block; the shipped
//! case list and EVALUATION.md's block are well formed.

mod common;

use common::temp_dir::TempDir;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn spslam() -> Command {
    Command::new(env!("CARGO_BIN_EXE_spslam"))
}

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn logs(output: &Output) -> String {
    format!(
        "status {:?}\nstdout:\n{}\nstderr:\n{}",
        output.status.code(),
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    )
}

fn evaluate(cases: &Path, out: &Path, data: &Path, extra: &[&str]) -> Output {
    spslam()
        .arg("evaluate")
        .arg("--cases")
        .arg(cases)
        .arg("--out")
        .arg(out)
        .arg("--data")
        .arg(data)
        .args(extra)
        .output()
        .expect("run spslam evaluate")
}

fn json(path: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn modified(path: &Path) -> std::time::SystemTime {
    std::fs::metadata(path)
        .and_then(|m| m.modified())
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The quick set, as `make test` runs it: two extractors on a synthetic
/// corner (RGB-D) and on KITTI 06 (stereo), and place recognition judged
/// against KITTI 06's ground truth. Measured (Intel Xeon, AVX-512
/// VNNI): every frame tracked; ATE 0.07-0.14 % of the path. Bounds: every
/// frame tracked, ATE <= 0.3 % of the path (2x the worst).
#[test]
fn the_quick_set_runs_summarises_skips_finished_cases_and_lists_commands() {
    let Some(data) = common::setup("cli_evaluate") else {
        return;
    };
    let dir = TempDir::new("evaluate", "quick");
    let out = dir.path().join("suite");
    let cases = repo().join("suite/cases.txt");
    let first = evaluate(&cases, &out, &data, &["--set", "quick", "--jobs", "2"]);
    assert!(first.status.success(), "{}", logs(&first));

    let summary = json(&out.join("summary.json"));
    let runs = summary["runs"].as_array().expect("runs");
    let names: Vec<&str> = runs.iter().filter_map(|r| r["case"].as_str()).collect();
    assert_eq!(
        names,
        [
            "quick_corner_rgbd_orb",
            "quick_corner_rgbd_sp_anms",
            "kitti06_stereo_orb",
            "kitti06_stereo_sp_anms"
        ],
        "{}",
        logs(&first)
    );
    assert!(summary["missing"].as_array().expect("missing").is_empty());
    for r in runs {
        let case = r["case"].as_str().unwrap_or("?");
        assert_eq!(r["tracked"], r["frames"], "{case}: every frame tracked");
        assert!(r["complete"].as_bool().unwrap_or(false), "{case}");
        let ate = r["ate_m"].as_f64().unwrap_or(f64::NAN);
        let path = r["path_m"].as_f64().unwrap_or(f64::NAN);
        assert!(
            100.0 * ate / path <= 0.3,
            "{case}: ATE {ate} m over {path} m"
        );
        let record = json(&out.join(format!("runs/{case}.case.json")));
        assert_eq!(record["exit_code"], 0, "{case}");
        assert!(record["definition"].as_str().unwrap_or("").contains(case));
        assert!(record["machine"].as_str().unwrap_or("").contains("cores"));
    }
    let expected_labels = ["ORB", "SuperPoint + ANMS", "ORB", "SuperPoint + ANMS"];
    let labels: Vec<&str> = runs
        .iter()
        .filter_map(|r| r["extractor"].as_str())
        .collect();
    assert_eq!(labels, expected_labels);
    let markdown = std::fs::read_to_string(out.join("summary.md")).expect("summary.md");
    for needle in [
        "| quick-corner-rgbd |",
        "| kitti06-stereo |",
        "machine:",
        "commit",
    ] {
        assert!(
            markdown.contains(needle),
            "summary.md lacks {needle}:\n{markdown}"
        );
    }
    assert!(modified(&out.join("summary_ate.png")) > std::time::UNIX_EPOCH);
    // The place case: spslam loops judged against KITTI 06's ground truth,
    // gathered in the summary.
    let place = summary["place"].as_array().expect("place");
    assert_eq!(place.len(), 1, "{}", logs(&first));
    assert_eq!(place[0]["case"], "place_kitti06");
    assert_eq!(place[0]["images"], 51);
    assert_eq!(place[0]["curves"].as_array().map(Vec::len), Some(4));
    for needle in ["### Place recognition", "| place_kitti06 | 51 | 0 |"] {
        assert!(
            markdown.contains(needle),
            "summary.md lacks {needle}:\n{markdown}"
        );
    }

    // Again: nothing re-runs.
    let report = out.join("runs/kitti06_stereo_orb/report.json");
    let before = modified(&report);
    let again = evaluate(&cases, &out, &data, &["--set", "quick"]);
    assert!(again.status.success(), "{}", logs(&again));
    assert!(
        String::from_utf8_lossy(&again.stderr).contains("5 of 5 cases already finished"),
        "{}",
        logs(&again)
    );
    assert_eq!(modified(&report), before, "a finished case ran again");

    // --list: one command per case, which runs as printed (and skips).
    let list = evaluate(&cases, &out, &data, &["--set", "quick", "--list"]);
    assert!(list.status.success(), "{}", logs(&list));
    let text = String::from_utf8_lossy(&list.stdout).to_string();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 5, "{text}");
    assert!(lines[4].ends_with("--case place_kitti06"), "{text}");
    assert!(lines[2].ends_with("--case kitti06_stereo_orb"), "{text}");
    let listed = Command::new("sh")
        .args(["-c", lines[2]])
        .output()
        .expect("run a listed command");
    assert!(listed.status.success(), "{}", logs(&listed));
    assert!(
        String::from_utf8_lossy(&listed.stderr).contains("1 of 1 cases already finished"),
        "{}",
        logs(&listed)
    );
}

/// A case whose line changes runs again; a case that fails is reported,
/// listed in the summary, and makes `spslam evaluate` exit with 1.
#[test]
fn a_changed_case_reruns_and_a_failed_case_is_reported() {
    let Some(data) = common::data_dir("cli_evaluate") else {
        return;
    };
    let dir = TempDir::new("evaluate", "rerun");
    let out = dir.path().join("suite");
    let cases = dir.path().join("cases.txt");
    let line = |frames: usize| {
        format!("case k06 kitti06 mine kitti:$DATA/kitti/sequences/06 --extractor orb --frames {frames}\n")
    };
    std::fs::write(&cases, line(8)).expect("write cases");
    let first = evaluate(&cases, &out, &data, &["--set", "mine"]);
    assert!(first.status.success(), "{}", logs(&first));
    let report = out.join("runs/k06/report.json");
    assert_eq!(json(&report)["frames_total"], 8);

    std::fs::write(&cases, line(10)).expect("write cases");
    let second = evaluate(&cases, &out, &data, &["--set", "mine"]);
    assert!(second.status.success(), "{}", logs(&second));
    assert_eq!(
        json(&report)["frames_total"],
        10,
        "the changed case ran again"
    );

    let broken = format!(
        "{}case nowhere kitti06 mine kitti:$DATA/no/such/sequence --extractor orb\n",
        line(10)
    );
    std::fs::write(&cases, broken).expect("write cases");
    let failed = evaluate(&cases, &out, &data, &["--set", "mine"]);
    assert_eq!(failed.status.code(), Some(1), "{}", logs(&failed));
    let stderr = String::from_utf8_lossy(&failed.stderr);
    assert!(
        stderr.contains("1 of 2 cases did not complete: nowhere"),
        "{}",
        logs(&failed)
    );
    let summary = json(&out.join("summary.json"));
    assert_eq!(summary["runs"].as_array().map(Vec::len), Some(1));
    assert_eq!(summary["missing"][0]["case"], "nowhere");
    assert!(summary["missing"][0]["why"]
        .as_str()
        .unwrap_or("")
        .contains("exit code 1"));
}

/// Mistakes in the case list name the file and line; nothing runs.
#[test]
fn a_bad_case_list_is_refused_with_its_line() {
    let dir = TempDir::new("evaluate", "bad");
    let cases = dir.path().join("cases.txt");
    std::fs::write(&cases, "# ok\ncase a g quick synth:@missing\n").expect("write cases");
    let out = dir.path().join("suite");
    let output = evaluate(&cases, &out, dir.path(), &["--set", "quick"]);
    assert_eq!(output.status.code(), Some(1), "{}", logs(&output));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("cases.txt:2:") && stderr.contains("`@missing`"),
        "{stderr}"
    );
    assert!(!out.exists(), "nothing may be written");
}

/// `--update-doc` replaces the block between the markers and keeps the
/// rest; a document without them is refused with the markers named.
#[test]
fn update_doc_replaces_only_the_generated_block() {
    let dir = TempDir::new("evaluate", "doc");
    let cases = dir.path().join("cases.txt");
    std::fs::write(&cases, "case a g s kitti:/none --extractor orb\n").expect("write cases");
    let out = dir.path().join("suite");
    let doc = dir.path().join("doc.md");
    let begin = "<!-- spslam evaluate: begin -->";
    let end = "<!-- spslam evaluate: end -->";
    std::fs::write(&doc, format!("# Title\n{begin}\nold table\n{end}\nafter\n")).expect("doc");
    let args = ["--set", "s", "--summary-only", "--update-doc"];
    let update = || {
        evaluate(
            &cases,
            &out,
            dir.path(),
            &[&args[..], &[doc.to_str().expect("utf-8")]].concat(),
        )
    };
    let output = update();
    assert!(output.status.success(), "{}", logs(&output));
    let text = std::fs::read_to_string(&doc).expect("doc");
    assert!(
        text.starts_with(&format!("# Title\n{begin}\nGenerated by `spslam evaluate`")),
        "{text}"
    );
    assert!(
        text.ends_with(&format!("- a: not run\n{end}\nafter\n")),
        "{text}"
    );
    assert!(!text.contains("old table"));

    // A document with the set's own block: that one is replaced, the plain
    // one kept.
    let (set_begin, set_end) = (
        "<!-- spslam evaluate s: begin -->",
        "<!-- spslam evaluate s: end -->",
    );
    std::fs::write(
        &doc,
        format!("{begin}\nstandard table\n{end}\n{set_begin}\nold table\n{set_end}\n"),
    )
    .expect("doc");
    let own = update();
    assert!(own.status.success(), "{}", logs(&own));
    let text = std::fs::read_to_string(&doc).expect("doc");
    assert!(
        text.starts_with(&format!(
            "{begin}\nstandard table\n{end}\n{set_begin}\nGenerated by"
        )),
        "{text}"
    );
    assert!(!text.contains("old table"), "{text}");

    std::fs::write(&doc, "no markers\n").expect("doc");
    let refused = update();
    assert_eq!(refused.status.code(), Some(1), "{}", logs(&refused));
    assert!(String::from_utf8_lossy(&refused.stderr).contains(begin));
}

/// The shipped case lists parse, every case of the standard set is
/// listed, every `$DATA` folder it names exists, and EVALUATION.md holds
/// the generated block.
#[test]
fn the_shipped_case_list_and_evaluation_md_are_well_formed() {
    let cases = repo().join("suite/cases.txt");
    let dir = TempDir::new("evaluate", "list");
    let data = common::shared_data_root();
    let list = evaluate(&cases, dir.path(), &data, &["--set", "all", "--list"]);
    assert!(list.status.success(), "{}", logs(&list));
    // The other case lists beside it (the phase-excess sweep) parse too.
    let others = std::fs::read_dir(repo().join("suite"))
        .expect("suite/")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p != &cases && p.extension().is_some_and(|x| x == "txt"));
    for other in others {
        let list = evaluate(&other, dir.path(), &data, &["--set", "all", "--list"]);
        assert!(
            list.status.success() && !list.stdout.is_empty(),
            "{}: {}",
            other.display(),
            logs(&list)
        );
    }
    let standard = evaluate(&cases, dir.path(), &data, &["--set", "standard", "--list"]);
    let count = String::from_utf8_lossy(&standard.stdout).lines().count();
    assert!(count >= 20, "the standard set has {count} cases");
    if data.is_dir() {
        let text = std::fs::read_to_string(&cases).expect("cases");
        for word in text.split_whitespace().filter(|w| w.contains("$DATA")) {
            let path = word
                .split_once(':')
                .map_or(word, |(_, p)| p)
                .replace("$DATA", &data.to_string_lossy());
            assert!(Path::new(&path).exists(), "{word}: {path} does not exist");
        }
    } else {
        common::missing(
            "the_shipped_case_list_and_evaluation_md_are_well_formed",
            "the shared data",
        );
    }
    let doc = std::fs::read_to_string(repo().join("EVALUATION.md")).expect("EVALUATION.md");
    let begin = doc
        .find("<!-- spslam evaluate: begin -->")
        .expect("begin marker");
    let end = doc
        .find("<!-- spslam evaluate: end -->")
        .expect("end marker");
    assert!(begin < end && doc[begin..end].contains("Generated by `spslam evaluate`"));
}
