//! `spslam evaluate`: the evaluation suite. Runs the cases of a case list
//! (`suite/cases.txt`: synthetic scenes and real sequences, each extractor
//! and sensor) as `spslam run` processes, several at a time, skipping the
//! finished ones, and writes the summary tables from their report.json
//! files (`OUT/summary.md`, `OUT/summary.json`, and with `--update-doc`
//! the generated block of `EVALUATION.md`).

mod cases;
mod layout;
mod loop_check_summary;
mod machine;
mod place_summary;
mod record;
mod runner;
mod summary;

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

use cases::{Case, CaseList, CaseTool, Substitutions};
use layout::SuiteLayout;
use runner::Runner;

/// The arguments of `spslam evaluate`.
#[derive(clap::Args)]
pub struct EvaluateArgs {
    /// The case list.
    #[arg(long, default_value = "suite/cases.txt")]
    cases: PathBuf,
    /// Output folder: OUT/scenes, OUT/runs, OUT/summary.md.
    #[arg(long, default_value = "out/suite")]
    out: PathBuf,
    /// The set of cases to run: quick, standard (see the case list) or all.
    #[arg(long, default_value = "standard")]
    set: String,
    /// Only this case (repeatable), instead of a set.
    #[arg(long = "case", value_name = "NAME")]
    only: Vec<String>,
    /// Cases run at once, each as its own `spslam run` process.
    #[arg(long, default_value_t = 1)]
    jobs: usize,
    /// Run the finished cases again (by default a case that completed with
    /// its current definition is not re-run).
    #[arg(long)]
    rerun: bool,
    /// Print one shell command per case and run nothing: hand the lines to
    /// a scheduler (a Slurm job array, GNU parallel), then run
    /// `spslam evaluate --summary-only` with the same --out.
    #[arg(long)]
    list: bool,
    /// Write the summary from the runs already in OUT; run nothing.
    #[arg(long, conflicts_with = "no_summary")]
    summary_only: bool,
    /// Run the cases and write no summary (the commands of --list use it,
    /// so that jobs running at once never write the same files).
    #[arg(long)]
    no_summary: bool,
    /// Replace the block between `<!-- spslam evaluate: begin -->` and
    /// `<!-- spslam evaluate: end -->` in this markdown file with the summary
    /// (for a set other than standard, its own block between `<!-- spslam
    /// evaluate SET: begin -->` and `... end -->` when the file has one).
    #[arg(long, value_name = "FILE")]
    update_doc: Option<PathBuf>,
    /// The shared data folder `$DATA` stands for [default: SPSLAM_DATA,
    /// else ../shared/data].
    #[arg(long)]
    data: Option<PathBuf>,
}

/// `path` made absolute against the current folder.
fn absolute(path: &Path) -> Result<PathBuf> {
    std::path::absolute(path).with_context(|| format!("resolving {}", path.display()))
}

/// A word quoted for a POSIX shell when it needs it.
fn shell_word(word: &str) -> String {
    let plain = word
        .chars()
        .all(|c| c.is_ascii_alphanumeric() || "-_./:=@,+".contains(c));
    if plain && !word.is_empty() {
        word.to_string()
    } else {
        format!("'{}'", word.replace('\'', "'\\''"))
    }
}

/// Checks that the data the cases need is there, before anything runs.
fn check_data(cases: &[&Case], data: &Path) -> Result<()> {
    let needs_data: Vec<&str> = cases
        .iter()
        .filter(|c| c.dataset.contains("$DATA"))
        .map(|c| c.name.as_str())
        .collect();
    if !needs_data.is_empty() && !data.is_dir() {
        bail!(
            "the shared data folder {} does not exist; cases {} need it: set SPSLAM_DATA or --data",
            data.display(),
            needs_data.join(", ")
        );
    }
    Ok(())
}

/// Runs `spslam evaluate`.
pub fn run_evaluate(args: EvaluateArgs) -> Result<()> {
    let list = CaseList::read(&args.cases)?;
    let cases = list
        .select(&args.set, &args.only)
        .map_err(|e| anyhow::anyhow!("{}: {e}", args.cases.display()))?;
    let out = absolute(&args.out)?;
    let layout = SuiteLayout::new(&out);
    let data = match &args.data {
        Some(d) => d.clone(),
        None => std::env::var_os("SPSLAM_DATA")
            .map(PathBuf::from)
            .unwrap_or_else(|| PathBuf::from("../shared/data")),
    };
    let data = absolute(&data)?;
    let exe = std::env::current_exe().context("finding the spslam executable")?;

    if args.list {
        let case_list = absolute(&args.cases)?;
        for case in &cases {
            let words = [
                exe.to_string_lossy().into_owned(),
                "evaluate".into(),
                "--cases".into(),
                case_list.to_string_lossy().into_owned(),
                "--out".into(),
                out.to_string_lossy().into_owned(),
                "--data".into(),
                data.to_string_lossy().into_owned(),
                "--no-summary".into(),
                "--case".into(),
                case.name.clone(),
            ];
            println!("{}", words.map(|w| shell_word(&w)).join(" "));
        }
        return Ok(());
    }

    let case_dir = args
        .cases
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let runner = Runner {
        exe,
        layout: &layout,
        list: &list,
        substitutions: Substitutions {
            data: data.clone(),
            suite: absolute(case_dir)?,
            scenes: layout.scenes(),
        },
        commit: machine::commit_of(case_dir),
        machine: machine::machine_description(),
    };

    let mut failures = Vec::new();
    if !args.summary_only {
        check_data(&cases, &data)?;
        let pending: Vec<&Case> = cases
            .iter()
            .copied()
            .filter(|c| args.rerun || !runner.is_finished(c))
            .collect();
        let done = cases.len() - pending.len();
        if done > 0 {
            eprintln!(
                "{done} of {} cases already finished with their current definition (--rerun runs them again)",
                cases.len()
            );
        }
        let mut scenes: Vec<&str> = pending.iter().filter_map(|c| c.scene.as_deref()).collect();
        scenes.sort_unstable();
        scenes.dedup();
        for name in scenes {
            if let Some(scene) = list.scenes.get(name) {
                eprintln!("scene {name}: spslam synth {}", scene.synth_args.join(" "));
                runner.ensure_scene(scene)?;
            }
        }
        for outcome in runner.run_all(&pending, args.jobs)? {
            if outcome.exit_code != Some(0) {
                failures.push(outcome.name);
            }
        }
    }

    if args.no_summary {
        return finish(&failures, cases.len(), &layout);
    }
    let (run_cases, place_cases): (Vec<&Case>, Vec<&Case>) =
        cases.iter().partition(|c| c.tool == CaseTool::Run);
    let (rows, missing) = summary::collect(&layout, &run_cases, |c| list.definition(c));
    let (place_rows, place_missing) =
        place_summary::collect(&layout, &place_cases, |c| list.definition(c));
    let set_name = if args.only.is_empty() {
        args.set.clone()
    } else {
        args.only.join(",")
    };
    // Only place cases chosen: no empty table of runs.
    let mut markdown = if run_cases.is_empty() {
        String::new()
    } else {
        summary::markdown(&rows, &missing, &set_name)
    };
    let loop_check_rows = loop_check_summary::collect(&layout, &run_cases, |c| list.definition(c));
    markdown.push_str(&loop_check_summary::markdown(&loop_check_rows));
    markdown.push_str(&place_summary::markdown(&place_rows, &place_missing));
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    let summary_md = out.join("summary.md");
    std::fs::write(&summary_md, &markdown)
        .with_context(|| format!("writing {}", summary_md.display()))?;
    let summary_json = out.join("summary.json");
    let all_missing: Vec<&summary::MissingRun> = missing.iter().chain(&place_missing).collect();
    let json = serde_json::json!({
        "runs": rows,
        "place": place_summary::json(&place_rows),
        "loop_check": loop_check_summary::json(&loop_check_rows),
        "missing": all_missing,
    });
    std::fs::write(&summary_json, serde_json::to_string_pretty(&json)? + "\n")
        .with_context(|| format!("writing {}", summary_json.display()))?;
    let plot = out.join("summary_ate.png");
    let _ = std::fs::remove_file(&plot);
    if !rows.is_empty() {
        if let Err(e) = summary::write_plot(&rows, &plot) {
            eprintln!("warning: the summary plot was not written: {e}");
        }
    }
    println!("{markdown}");
    eprintln!(
        "summary: {}, {} and {}",
        summary_md.display(),
        summary_json.display(),
        plot.display()
    );

    if let Some(doc) = &args.update_doc {
        let text =
            std::fs::read_to_string(doc).with_context(|| format!("reading {}", doc.display()))?;
        // The set's own block; a document without one takes the summary in
        // the plain block.
        let (begin, end) = summary::markers(&args.set);
        let Some(updated) =
            summary::replace_block_between(&text, &markdown, &begin, &end).or_else(|| {
                summary::replace_block_between(
                    &text,
                    &markdown,
                    summary::BEGIN_MARKER,
                    summary::END_MARKER,
                )
            })
        else {
            let plain = if begin == summary::BEGIN_MARKER {
                String::new()
            } else {
                format!(
                    " (or `{}` and `{}`)",
                    summary::BEGIN_MARKER,
                    summary::END_MARKER
                )
            };
            bail!(
                "{} has no block to replace: put the lines `{begin}` and `{end}`{plain} where the summary goes",
                doc.display(),
            );
        };
        std::fs::write(doc, updated).with_context(|| format!("writing {}", doc.display()))?;
        eprintln!("updated the generated block of {}", doc.display());
    }

    finish(&failures, cases.len(), &layout)
}

/// The command's end: an error naming the cases that did not complete.
fn finish(failures: &[String], cases: usize, layout: &SuiteLayout) -> Result<()> {
    if !failures.is_empty() {
        bail!(
            "{} of {cases} cases did not complete: {} (their logs are in {})",
            failures.len(),
            failures.join(", "),
            layout.runs().display()
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::shell_word;

    #[test]
    fn shell_words_are_quoted_when_they_need_it() {
        assert_eq!(shell_word("/a/b-c_d.e:f=g@h,i+j"), "/a/b-c_d.e:f=g@h,i+j");
        assert_eq!(shell_word("a b"), "'a b'");
        assert_eq!(shell_word("it's"), "'it'\\''s'");
        assert_eq!(shell_word(""), "''");
        assert_eq!(shell_word("$DATA"), "'$DATA'");
    }
}
