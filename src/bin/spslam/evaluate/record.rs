//! What the suite writes beside each run and scene, so that a later
//! invocation (or the summary after a cluster run) knows what ran, where
//! and with which definition.

use std::path::Path;

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};

/// `OUT/runs/NAME.case.json`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CaseRecord {
    /// The case's line and its scene's (see `CaseList::definition`).
    pub definition: String,
    /// The commit of the checkout the case list came from.
    pub commit: String,
    /// The machine, in words.
    pub machine: String,
    /// `spslam run`'s exit code (None: ended by a signal).
    pub exit_code: Option<i32>,
    /// Wall time of the run, s.
    pub seconds: f64,
}

/// `OUT/scenes/NAME/scene.json`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SceneRecord {
    /// `spslam synth`'s arguments.
    pub synth_args: Vec<String>,
}

fn read_json<T: for<'de> Deserialize<'de>>(path: &Path) -> Result<T> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    serde_json::from_str(&text).with_context(|| format!("parsing {}", path.display()))
}

fn write_json<T: Serialize>(value: &T, path: &Path) -> Result<()> {
    let text = serde_json::to_string_pretty(value)?;
    std::fs::write(path, text + "\n").with_context(|| format!("writing {}", path.display()))
}

impl CaseRecord {
    /// Reads a case record.
    pub fn read(path: &Path) -> Result<Self> {
        read_json(path)
    }

    /// Writes the record.
    pub fn write(&self, path: &Path) -> Result<()> {
        write_json(self, path)
    }
}

impl SceneRecord {
    /// Reads a scene record.
    pub fn read(path: &Path) -> Result<Self> {
        read_json(path)
    }

    /// Writes the record.
    pub fn write(&self, path: &Path) -> Result<()> {
        write_json(self, path)
    }
}
