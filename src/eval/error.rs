//! Errors of trajectory reading, association, alignment and plotting.

use std::path::PathBuf;

/// Everything that can go wrong in [`crate::eval`].
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    /// A file could not be opened, read or written.
    #[error("cannot access {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A row of a trajectory file could not be parsed.
    #[error("{path}:{line}: {reason}")]
    Malformed {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong with the row.
        reason: String,
    },
    /// A trajectory file holds no poses.
    #[error("{path}: no poses")]
    Empty {
        /// The file.
        path: PathBuf,
    },
    /// A format name that is not `kitti`, `tum` or `euroc`.
    #[error("unknown trajectory format {name:?} (expected kitti, tum or euroc)")]
    UnknownFormat {
        /// The name given.
        name: String,
    },
    /// The format of a file could not be detected from its first data row.
    #[error("cannot detect the format of {path}: first data row has {columns} columns (kitti has 12, tum 8; euroc files end in .csv)")]
    UndetectedFormat {
        /// The file.
        path: PathBuf,
        /// Number of columns in the first data row.
        columns: usize,
    },
    /// A KITTI times file does not have one stamp per pose.
    #[error("{path}: {times} timestamps for {poses} poses")]
    TimesMismatch {
        /// The times file.
        path: PathBuf,
        /// Timestamps read.
        times: usize,
        /// Poses in the trajectory.
        poses: usize,
    },
    /// Two trajectories that must correspond pose by pose differ in length.
    #[error("the trajectories differ in length: {reference} reference poses, {estimate} estimated poses")]
    LengthMismatch {
        /// Poses in the reference.
        reference: usize,
        /// Poses in the estimate.
        estimate: usize,
    },
    /// No timestamps of the two trajectories lie within the tolerance.
    #[error("no timestamps match within {max_diff} s ({reference} reference, {estimate} estimated stamps)")]
    NoAssociation {
        /// The tolerance in seconds.
        max_diff: f64,
        /// Stamps in the reference.
        reference: usize,
        /// Stamps in the estimate.
        estimate: usize,
    },
    /// A pose matrix given in memory whose 3×3 part is not a rotation.
    #[error("pose {index}: the 3×3 part is not a rotation (determinant ≤ 0 or not finite)")]
    NotARotation {
        /// The pose's index.
        index: usize,
    },
    /// Timestamps given in memory that are not one per pose.
    #[error("{stamps} timestamps for {poses} poses")]
    StampCount {
        /// Timestamps given.
        stamps: usize,
        /// Poses given.
        poses: usize,
    },
    /// The point sets are degenerate (fewer than two independent directions), so no alignment exists.
    #[error("degenerate point sets ({points} points): Umeyama alignment is not possible")]
    DegenerateAlignment {
        /// Number of point pairs.
        points: usize,
    },
    /// An evaluation was asked of trajectories without poses.
    #[error("no poses to evaluate")]
    NoPoses,
    /// A plot could not be drawn or written.
    #[error("cannot write the plot {path}: {message}")]
    Plot {
        /// The image file.
        path: PathBuf,
        /// The plotting library's message.
        message: String,
    },
}

/// Result alias for [`EvalError`].
pub type Result<T> = std::result::Result<T, EvalError>;
