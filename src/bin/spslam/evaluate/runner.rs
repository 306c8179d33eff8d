//! Runs the suite's scenes and cases as child processes of this `spslam`
//! (`spslam synth`, `spslam run`), several at a time, skipping what is done.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};

use super::cases::{Case, CaseList, CaseTool, Scene, Substitutions};
use super::layout::SuiteLayout;
use super::record::{CaseRecord, SceneRecord};

/// Where the cases run and with what.
pub struct Runner<'a> {
    /// This executable (`spslam`).
    pub exe: PathBuf,
    /// The output folders.
    pub layout: &'a SuiteLayout,
    /// The case list.
    pub list: &'a CaseList,
    /// What `$DATA`, `$SUITE` and `@SCENE` stand for.
    pub substitutions: Substitutions,
    /// The commit of the case list's checkout.
    pub commit: String,
    /// The machine, in words.
    pub machine: String,
}

/// How one case's run ended.
#[derive(Debug, Clone)]
pub struct CaseOutcome {
    /// The case.
    pub name: String,
    /// `spslam run`'s exit code (None: it could not be started or was killed).
    pub exit_code: Option<i32>,
    /// The log file (stdout and stderr of the run).
    pub log: PathBuf,
}

impl Runner<'_> {
    /// Whether the case ran to completion with its current definition.
    pub fn is_finished(&self, case: &Case) -> bool {
        let Ok(record) = CaseRecord::read(&self.layout.case_record(&case.name)) else {
            return false;
        };
        let result = match case.tool {
            CaseTool::Run => self.layout.report(&case.name),
            CaseTool::Loops => self.layout.curves(&case.name),
        };
        record.exit_code == Some(0)
            && record.definition == self.list.definition(case)
            && result.is_file()
    }

    /// Writes the scene unless it is there with the same arguments. The
    /// scene is written to a temporary folder and renamed into place, so
    /// jobs started by a scheduler never see half a scene.
    pub fn ensure_scene(&self, scene: &Scene) -> Result<()> {
        let folder = self.layout.scene(&scene.name);
        let record_path = folder.join("scene.json");
        if let Ok(record) = SceneRecord::read(&record_path) {
            if record.synth_args == scene.synth_args {
                return Ok(());
            }
            std::fs::remove_dir_all(&folder)
                .with_context(|| format!("removing the stale scene {}", folder.display()))?;
        }
        // Unique per process and moment: jobs on several cluster nodes may
        // share the folder (and their process ids).
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos());
        let staging =
            self.layout
                .scenes()
                .join(format!(".{}.{}.{nanos}", scene.name, std::process::id()));
        let _ = std::fs::remove_dir_all(&staging);
        std::fs::create_dir_all(self.layout.scenes())
            .with_context(|| format!("creating {}", self.layout.scenes().display()))?;
        let log = self.layout.scenes().join(format!("{}.log", scene.name));
        let status = self
            .command(&log)?
            .arg("synth")
            .arg("--out")
            .arg(&staging)
            .args(&scene.synth_args)
            .status()
            .with_context(|| format!("starting {} synth", self.exe.display()))?;
        if !status.success() {
            let _ = std::fs::remove_dir_all(&staging);
            bail!(
                "scene `{}`: spslam synth {} failed ({status}); see {}",
                scene.name,
                scene.synth_args.join(" "),
                log.display()
            );
        }
        SceneRecord {
            synth_args: scene.synth_args.clone(),
        }
        .write(&staging.join("scene.json"))?;
        if std::fs::rename(&staging, &folder).is_err() {
            // Another job wrote the same scene first.
            let _ = std::fs::remove_dir_all(&staging);
            if !folder.join("scene.json").is_file() {
                bail!(
                    "cannot move scene `{}` into {}",
                    scene.name,
                    folder.display()
                );
            }
        }
        Ok(())
    }

    /// A command of this executable with stdout and stderr going to `log`.
    fn command(&self, log: &Path) -> Result<Command> {
        let file = std::fs::File::create(log)
            .with_context(|| format!("creating the log {}", log.display()))?;
        let err = file
            .try_clone()
            .with_context(|| format!("opening the log {}", log.display()))?;
        let mut command = Command::new(&self.exe);
        command
            .stdin(Stdio::null())
            .stdout(Stdio::from(file))
            .stderr(Stdio::from(err));
        Ok(command)
    }

    /// The `spslam run` (or `spslam loops`) arguments of a case (after `spslam`).
    pub fn run_arguments(&self, case: &Case) -> Vec<String> {
        if case.tool == CaseTool::Loops {
            let mut args = vec![
                "loops".to_string(),
                "--dataset".into(),
                case.resolved_dataset(&self.substitutions),
                "--curves".into(),
                self.layout
                    .curves(&case.name)
                    .to_string_lossy()
                    .into_owned(),
            ];
            args.extend(case.resolved_args(&self.substitutions));
            return args;
        }
        let mut args = vec![
            "run".to_string(),
            "--dataset".into(),
            case.resolved_dataset(&self.substitutions),
            "--out".into(),
            self.layout.run(&case.name).to_string_lossy().into_owned(),
        ];
        // Inline mapping (deterministic) unless the case asks for the thread.
        if !case.run_args.iter().any(|a| a == "--mapping-thread") {
            args.push("--inline-mapping".into());
        }
        args.extend(case.resolved_args(&self.substitutions));
        args
    }

    /// Runs one case (its scene first) and records how it ended.
    pub fn run_case(&self, case: &Case) -> Result<CaseOutcome> {
        if let Some(scene) = case.scene.as_ref().and_then(|s| self.list.scenes.get(s)) {
            self.ensure_scene(scene)?;
        }
        let record_path = self.layout.case_record(&case.name);
        let _ = std::fs::remove_file(&record_path);
        let run_folder = self.layout.run(&case.name);
        if run_folder.exists() {
            std::fs::remove_dir_all(&run_folder)
                .with_context(|| format!("removing the old run {}", run_folder.display()))?;
        }
        std::fs::create_dir_all(self.layout.runs())
            .with_context(|| format!("creating {}", self.layout.runs().display()))?;
        if case.tool == CaseTool::Loops {
            // `spslam loops` writes one file into the case's folder.
            std::fs::create_dir_all(&run_folder)
                .with_context(|| format!("creating {}", run_folder.display()))?;
        }
        let log = self.layout.log(&case.name);
        let started = Instant::now();
        let status = self
            .command(&log)?
            .args(self.run_arguments(case))
            .status()
            .with_context(|| format!("starting {} run", self.exe.display()))?;
        let record = CaseRecord {
            definition: self.list.definition(case),
            commit: self.commit.clone(),
            machine: self.machine.clone(),
            exit_code: status.code(),
            seconds: started.elapsed().as_secs_f64(),
        };
        record.write(&record_path)?;
        Ok(CaseOutcome {
            name: case.name.clone(),
            exit_code: status.code(),
            log,
        })
    }

    /// Runs `cases` with `jobs` at a time, with a progress bar over cases.
    /// A case that cannot even be started ends the suite; a run that fails
    /// is recorded and the others go on.
    pub fn run_all(&self, cases: &[&Case], jobs: usize) -> Result<Vec<CaseOutcome>> {
        let bar = ProgressBar::new(cases.len() as u64);
        bar.set_style(
            ProgressStyle::with_template(
                "{bar:30} {pos}/{len} cases [{elapsed_precise}<{eta_precise}] {msg}",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        let next = AtomicUsize::new(0);
        let running = Mutex::new(BTreeSet::<String>::new());
        let outcomes = Mutex::new(Vec::<Result<CaseOutcome>>::new());
        let show = |running: &BTreeSet<String>| {
            bar.set_message(running.iter().cloned().collect::<Vec<_>>().join(", "));
        };
        std::thread::scope(|scope| {
            for _ in 0..jobs.max(1) {
                scope.spawn(|| loop {
                    let index = next.fetch_add(1, Ordering::SeqCst);
                    let Some(case) = cases.get(index) else { break };
                    {
                        let mut set = running.lock().unwrap_or_else(|p| p.into_inner());
                        set.insert(case.name.clone());
                        show(&set);
                    }
                    let outcome = self.run_case(case);
                    {
                        let mut set = running.lock().unwrap_or_else(|p| p.into_inner());
                        set.remove(&case.name);
                        show(&set);
                    }
                    if let Ok(o) = &outcome {
                        if o.exit_code != Some(0) {
                            let tool = match case.tool {
                                CaseTool::Run => "run",
                                CaseTool::Loops => "loops",
                            };
                            bar.println(format!(
                                "case {}: spslam {tool} ended with {}; see {}",
                                o.name,
                                o.exit_code
                                    .map_or("a signal".to_string(), |c| format!("exit code {c}")),
                                o.log.display()
                            ));
                        }
                    }
                    let failed_to_start = outcome.is_err();
                    outcomes
                        .lock()
                        .unwrap_or_else(|p| p.into_inner())
                        .push(outcome);
                    bar.inc(1);
                    if failed_to_start {
                        // Stop taking new cases: the next would fail alike.
                        next.store(cases.len(), Ordering::SeqCst);
                    }
                });
            }
        });
        bar.finish_and_clear();
        outcomes
            .into_inner()
            .unwrap_or_else(|p| p.into_inner())
            .into_iter()
            .collect()
    }
}
