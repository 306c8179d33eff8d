//! Loading ONNX Runtime's shared library once per process.
//!
//! `ort` allows one library and one environment per process. The first
//! extractor decides which library is loaded; later requests for another path
//! reuse the loaded one and log a warning.

use std::path::{Path, PathBuf};
use std::sync::Mutex;

use ort::environment::Environment;

use super::FeatureError;

/// The library file name inside the set-up folder.
pub const ORT_LIBRARY_FILE: &str = "libonnxruntime.so.1.31.1";

struct Loaded {
    path: PathBuf,
    environment: Environment,
}

static LOADED: Mutex<Option<Loaded>> = Mutex::new(None);

/// Whether a library has been loaded in this process (ONNX Runtime's API
/// may only be called after that).
pub fn is_loaded() -> bool {
    LOADED
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
        .is_some()
}

/// Where the library is looked for, in order: the explicit path, then
/// `ORT_DYLIB_PATH`, then `.deps/onnxruntime/` in the crate root. The first one
/// that is given is used; it is an error when that file does not exist.
pub fn resolve_library_path(explicit: Option<&Path>) -> (PathBuf, &'static str) {
    if let Some(path) = explicit {
        return (path.to_path_buf(), "the extractor config");
    }
    if let Some(path) = std::env::var_os("ORT_DYLIB_PATH").filter(|p| !p.is_empty()) {
        return (PathBuf::from(path), "ORT_DYLIB_PATH");
    }
    let default = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join(".deps/onnxruntime")
        .join(ORT_LIBRARY_FILE);
    (default, "the set-up folder")
}

/// Loads the library (first call only) and returns the process-wide environment.
pub fn environment(explicit: Option<&Path>) -> Result<Environment, FeatureError> {
    let mut loaded = LOADED
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    let (path, source) = resolve_library_path(explicit);
    if let Some(existing) = loaded.as_ref() {
        if existing.path != path {
            tracing::warn!(
                "ONNX Runtime is already loaded from {}; ignoring {} from {source}",
                existing.path.display(),
                path.display()
            );
        }
        return Ok(existing.environment.clone());
    }
    if !path.is_file() {
        return Err(FeatureError::RuntimeLibrary {
            reason: format!("{} (from {source}) does not exist", path.display()),
        });
    }
    let builder = ort::init_from(&path).map_err(|e| FeatureError::RuntimeLibrary {
        reason: format!("{} (from {source}): {e}", path.display()),
    })?;
    let environment =
        builder
            .with_name("spslam")
            .build()
            .map_err(|e| FeatureError::RuntimeLibrary {
                reason: format!("creating the environment failed: {e}"),
            })?;
    *loaded = Some(Loaded {
        path,
        environment: environment.clone(),
    });
    Ok(environment)
}
