//! Errors from reading settings files.

use std::path::PathBuf;

/// What went wrong reading an ORB-SLAM3-style settings file.
#[derive(Debug, thiserror::Error)]
pub enum SettingsError {
    /// The file does not exist.
    #[error("settings file {path} does not exist")]
    NotFound {
        /// The path given.
        path: PathBuf,
    },
    /// OpenCV's FileStorage could not parse the file.
    #[error("cannot parse settings file {path} (it must be OpenCV YAML starting with `%YAML:1.0`): {reason}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// OpenCV's message.
        reason: String,
    },
    /// A required key is absent.
    #[error("settings file {path} lacks `{key}`{hint}")]
    Missing {
        /// The file.
        path: PathBuf,
        /// The key looked for (the first of its accepted spellings).
        key: String,
        /// Extra advice, empty or starting with "; ".
        hint: String,
    },
    /// A key holds the wrong type of value.
    #[error("settings file {path}: `{key}` must be {expected}")]
    WrongType {
        /// The file.
        path: PathBuf,
        /// The key.
        key: String,
        /// What it should hold.
        expected: &'static str,
    },
    /// A value is out of its valid range.
    #[error("settings file {path}: `{key}` = {value} is invalid: {reason}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// The key.
        key: String,
        /// The value found, as text.
        value: String,
        /// Why it is rejected.
        reason: &'static str,
    },
}

/// Result alias for settings.
pub type Result<T> = std::result::Result<T, SettingsError>;
