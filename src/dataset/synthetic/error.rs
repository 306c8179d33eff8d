//! Errors of the synthetic-sequence generator.

use std::path::PathBuf;

/// Everything that can go wrong while configuring or writing a synthetic sequence.
#[derive(Debug, thiserror::Error)]
pub enum SyntheticError {
    /// A configuration value is out of range.
    #[error("invalid synthetic config: `{field}` {reason}")]
    InvalidConfig {
        /// The offending field.
        field: &'static str,
        /// What is wrong and what is accepted.
        reason: String,
    },
    /// The output sequence folder already holds files.
    #[error(
        "{} is not empty; choose another output folder or allow overwriting (`--overwrite`)",
        path.display()
    )]
    OutputNotEmpty {
        /// The sequence folder.
        path: PathBuf,
    },
    /// A folder or file could not be created, written or removed.
    #[error("cannot write {}: {source}", path.display())]
    Io {
        /// The path being written.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// OpenCV refused to encode or write an image.
    #[error("cannot write the image {}: {reason}", path.display())]
    ImageWrite {
        /// The image file.
        path: PathBuf,
        /// OpenCV's error, or that `imwrite` returned false.
        reason: String,
    },
}

/// Result alias for the synthetic-sequence generator.
pub type Result<T> = std::result::Result<T, SyntheticError>;

impl SyntheticError {
    /// Wraps an I/O error with the path it concerns.
    pub(crate) fn io(path: &std::path::Path) -> impl FnOnce(std::io::Error) -> Self + '_ {
        move |source| Self::Io {
            path: path.to_path_buf(),
            source,
        }
    }
}
