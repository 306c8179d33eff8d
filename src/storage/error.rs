//! What can go wrong with a map file, each naming the file and the fault.

use std::path::PathBuf;

use crate::map::InvariantViolation;

/// A map file that cannot be written, read or used.
#[derive(Debug, thiserror::Error)]
pub enum StorageError {
    /// The file system refused.
    #[error("{path}: {action} failed: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What was being done ("read", "write", "rename", …).
        action: &'static str,
        /// The cause.
        source: std::io::Error,
    },
    /// The file does not start with the map file's magic number.
    #[error("{path} is not an spslam map file (no SPSLMAP magic number at its start)")]
    NotAMapFile {
        /// The file.
        path: PathBuf,
    },
    /// A format version this build does not read.
    #[error("{path} is a map file of format version {found}; this spslam reads version {supported} (save the map again with a matching spslam)")]
    UnsupportedVersion {
        /// The file.
        path: PathBuf,
        /// The file's version.
        found: u32,
        /// The version this build reads.
        supported: u32,
    },
    /// The file is shorter (or longer) than its header says.
    #[error("{path} is truncated or padded: the header announces {expected} payload bytes, the file holds {actual}")]
    Truncated {
        /// The file.
        path: PathBuf,
        /// Payload bytes announced.
        expected: u64,
        /// Payload bytes present.
        actual: u64,
    },
    /// The payload does not match its checksum.
    #[error("{path} is corrupted: payload CRC-32 {computed:#010x}, header says {stored:#010x}")]
    ChecksumMismatch {
        /// The file.
        path: PathBuf,
        /// The checksum in the header.
        stored: u32,
        /// The checksum of the payload read.
        computed: u32,
    },
    /// The payload passes its checksum but does not decode.
    #[error("{path} does not decode as a map: {reason}")]
    Corrupt {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// A stored map that is not consistent.
    #[error("{path}: map {map} is inconsistent: {violation}")]
    Inconsistent {
        /// The file.
        path: PathBuf,
        /// The atlas map.
        map: usize,
        /// The first inconsistency.
        violation: InvariantViolation,
    },
    /// A map made with another model or codebook than the one in use.
    #[error("{path} was built with {what} {file_hash}, but this run uses {what} {current_hash}: localising in it would mismatch descriptors (use the {what} it was built with)")]
    BuiltWithAnother {
        /// The file.
        path: PathBuf,
        /// "model" or "codebook".
        what: &'static str,
        /// The hash stored in the file.
        file_hash: String,
        /// The hash of the one in use.
        current_hash: String,
    },
    /// A save stopped by the test hook before it completed.
    #[error("{path}: save interrupted after {written} bytes (test hook); the previous file is untouched")]
    Interrupted {
        /// The file.
        path: PathBuf,
        /// Bytes written to the temporary file.
        written: usize,
    },
}
