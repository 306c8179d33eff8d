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
    /// A codebook file does not start with the codebook magic bytes.
    #[error("{path} is not a VLAD codebook (bad magic bytes)")]
    BadMagic {
        /// The file.
        path: PathBuf,
    },
    /// A codebook file has a format version this build cannot read.
    #[error(
        "{path}: codebook format version {version} is not supported (this build reads {supported})"
    )]
    UnsupportedVersion {
        /// The file.
        path: PathBuf,
        /// The version in the file.
        version: u32,
        /// The version this build reads.
        supported: u32,
    },
    /// A codebook file is shorter or longer than its header says.
    #[error("{path}: codebook file holds {actual} bytes; its header needs {expected}")]
    WrongLength {
        /// The file.
        path: PathBuf,
        /// Bytes the header implies (0 when even the header is incomplete).
        expected: u64,
        /// Bytes in the file.
        actual: u64,
    },
    /// A codebook header field is out of range (k or the dimension is 0,
    /// the whitening is larger than the descriptor).
    #[error("{path}: invalid codebook header: {reason}")]
    BadHeader {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// A codebook's payload does not match its checksum (the file is corrupt).
    #[error("{path}: codebook checksum mismatch (stored {stored:#010x}, computed {computed:#010x}); the file is corrupt")]
    Checksum {
        /// The file.
        path: PathBuf,
        /// The CRC-32 stored in the file.
        stored: u32,
        /// The CRC-32 of the bytes read.
        computed: u32,
    },
    /// A codebook was trained for other extractor settings than those in use.
    #[error("{path} was trained for extractor settings {found:#018x}, but the extractor in use has settings {expected:#018x}; retrain it with `spslam vocab train --format vlad` and the same extractor options")]
    CodebookMismatch {
        /// The settings hash of the extractor in use.
        expected: u64,
        /// The settings hash stored in the codebook.
        found: u64,
        /// The codebook file.
        path: PathBuf,
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
