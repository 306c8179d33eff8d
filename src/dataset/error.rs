//! The error type shared by every dataset reader.

use std::path::PathBuf;

/// Everything that can go wrong while opening a dataset or rectifying images.
#[derive(Debug, thiserror::Error)]
pub enum DatasetError {
    /// A folder the layout requires does not exist.
    #[error("missing folder {}", path.display())]
    MissingFolder {
        /// The folder that was expected.
        path: PathBuf,
    },
    /// A file the layout requires does not exist.
    #[error("missing file {}", path.display())]
    MissingFile {
        /// The file that was expected.
        path: PathBuf,
    },
    /// A file or folder exists but could not be read.
    #[error("cannot read {}: {source}", path.display())]
    Io {
        /// The file or folder being read.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// A line of a text file could not be parsed.
    #[error("{}:{line}: {reason}", path.display())]
    MalformedRow {
        /// The file holding the line.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong with the line.
        reason: String,
    },
    /// A required key is absent from a calibration or settings file.
    #[error("{}: missing key `{key}`", path.display())]
    MissingKey {
        /// The file searched.
        path: PathBuf,
        /// The key that was not found.
        key: String,
    },
    /// The two cameras of a stereo sequence hold different numbers of images.
    #[error(
        "{left} images in {} but {right} in {}",
        left_dir.display(),
        right_dir.display()
    )]
    ImageCountMismatch {
        /// Folder of the left camera's images.
        left_dir: PathBuf,
        /// Number of left images.
        left: usize,
        /// Folder of the right camera's images.
        right_dir: PathBuf,
        /// Number of right images.
        right: usize,
    },
    /// A timestamp file does not have one row per image.
    #[error("{}: {timestamps} timestamps for {images} images", path.display())]
    TimestampCountMismatch {
        /// The timestamp file.
        path: PathBuf,
        /// Number of timestamps read.
        timestamps: usize,
        /// Number of images found.
        images: usize,
    },
    /// A sequence holds no usable frame.
    #[error("no frames in {}", path.display())]
    NoFrames {
        /// The sequence folder.
        path: PathBuf,
    },
    /// The calibration cannot be used (e.g. a singular extrinsic, a negative baseline).
    #[error("invalid calibration: {reason}")]
    InvalidCalibration {
        /// What is wrong.
        reason: String,
    },
    /// An image given for rectification does not have the calibrated size.
    #[error(
        "image is {width}x{height} but the calibration is for {expected_width}x{expected_height}"
    )]
    ImageSizeMismatch {
        /// Width of the image given.
        width: i32,
        /// Height of the image given.
        height: i32,
        /// Calibrated width.
        expected_width: i32,
        /// Calibrated height.
        expected_height: i32,
    },
    /// An OpenCV call failed.
    #[error("OpenCV failed while {context}: {source}")]
    OpenCv {
        /// What was being done.
        context: &'static str,
        /// The OpenCV error.
        #[source]
        source: opencv::Error,
    },
}

/// Result alias for the dataset readers.
pub type Result<T> = std::result::Result<T, DatasetError>;

impl DatasetError {
    /// Builds a [`DatasetError::MalformedRow`].
    pub(crate) fn row(path: &std::path::Path, line: usize, reason: impl Into<String>) -> Self {
        Self::MalformedRow {
            path: path.to_path_buf(),
            line,
            reason: reason.into(),
        }
    }

    /// Wraps an OpenCV error with what was being done.
    pub(crate) fn cv(context: &'static str) -> impl FnOnce(opencv::Error) -> Self {
        move |source| Self::OpenCv { context, source }
    }
}
