//! The folders of a suite's output: `OUT/scenes/NAME` (synthetic
//! sequences), `OUT/runs/NAME` (one `spslam run` each, with `NAME.log` and
//! `NAME.case.json` beside it) and the summary files in `OUT`.

use std::path::{Path, PathBuf};

/// The output folder of `spslam evaluate`.
pub struct SuiteLayout {
    out: PathBuf,
}

impl SuiteLayout {
    /// The layout under `out`.
    pub fn new(out: &Path) -> Self {
        Self {
            out: out.to_path_buf(),
        }
    }

    /// The folder of the synthetic scenes.
    pub fn scenes(&self) -> PathBuf {
        self.out.join("scenes")
    }

    /// One scene's folder (`spslam synth --out`).
    pub fn scene(&self, name: &str) -> PathBuf {
        self.scenes().join(name)
    }

    /// The folder of the runs.
    pub fn runs(&self) -> PathBuf {
        self.out.join("runs")
    }

    /// One case's run folder (`spslam run --out`).
    pub fn run(&self, name: &str) -> PathBuf {
        self.runs().join(name)
    }

    /// One case's report.json.
    pub fn report(&self, name: &str) -> PathBuf {
        self.run(name).join("report.json")
    }

    /// One place case's curves (`spslam loops --curves`).
    pub fn curves(&self, name: &str) -> PathBuf {
        self.run(name).join("curves.json")
    }

    /// One case's log (stdout and stderr of `spslam run`).
    pub fn log(&self, name: &str) -> PathBuf {
        self.runs().join(format!("{name}.log"))
    }

    /// One case's record: its definition, commit, machine and exit code.
    pub fn case_record(&self, name: &str) -> PathBuf {
        self.runs().join(format!("{name}.case.json"))
    }
}
