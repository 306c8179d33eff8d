//! Errors of the place-recognition layer.

use std::path::PathBuf;

/// What went wrong while clustering descriptors or reading and writing a
/// vocabulary.
#[derive(Debug, thiserror::Error)]
pub enum PlaceError {
    /// A parameter is out of range.
    #[error("invalid {name} = {value}: {expected}")]
    InvalidParameter {
        /// The parameter's name.
        name: &'static str,
        /// The value given, as text.
        value: String,
        /// What is accepted.
        expected: &'static str,
    },
    /// There is nothing to cluster.
    #[error("no descriptors to cluster: {reason}")]
    NoDescriptors {
        /// Where they were expected.
        reason: String,
    },
    /// The rows do not have the length the metric expects.
    #[error("descriptor rows hold {actual} values each; the metric expects {expected}")]
    RowLength {
        /// Values per row the metric works on.
        expected: usize,
        /// Values per row given.
        actual: usize,
    },
    /// A buffer's length is not a whole number of rows, or its image
    /// lengths do not add up to its rows.
    #[error("inconsistent descriptor data: {reason}")]
    Inconsistent {
        /// What does not add up.
        reason: String,
    },
    /// A descriptor value cannot be written (NaN or infinite).
    #[error(
        "node {node} has a non-finite descriptor value; a vocabulary file needs finite numbers"
    )]
    NonFinite {
        /// The node's id.
        node: usize,
    },
    /// A file could not be created, written, renamed or read.
    #[error("cannot {action} {path}: {source}")]
    Io {
        /// What was being done ("write", "read", ...).
        action: &'static str,
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// A vocabulary file does not follow the DBoW2 text format.
    #[error("{path}:{line}: not a DBoW2 text vocabulary: {reason}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// The 1-based line number (the line after the last one for problems at the end).
        line: usize,
        /// What is wrong.
        reason: String,
    },
}

impl PlaceError {
    /// An [`InvalidParameter`](Self::InvalidParameter) error.
    pub(crate) fn invalid(
        name: &'static str,
        value: impl ToString,
        expected: &'static str,
    ) -> Self {
        Self::InvalidParameter {
            name,
            value: value.to_string(),
            expected,
        }
    }
}
