use crate::features::{DescriptorKind, FeatureError};

/// What can go wrong while matching.
#[derive(Debug, thiserror::Error)]
pub enum MatchError {
    /// The two sides hold descriptors of different kinds or lengths.
    #[error("cannot compare {query} descriptors with {train} descriptors")]
    KindMismatch {
        /// The query side's kind.
        query: DescriptorKind,
        /// The train side's kind.
        train: DescriptorKind,
    },
    /// A feature set does not hold one descriptor row per keypoint.
    #[error("{keypoints} keypoints but {descriptors} descriptor rows")]
    RowCount {
        /// Keypoints.
        keypoints: usize,
        /// Descriptor rows.
        descriptors: usize,
    },
    /// A train layout does not hold one position and one rival distance
    /// per train row.
    #[error(
        "{rows} train rows but {positions} positions and {distances} rival distances in the layout"
    )]
    LayoutLength {
        /// Train rows.
        rows: usize,
        /// Positions given.
        positions: usize,
        /// Rival distances given.
        distances: usize,
    },
    /// A parameter is out of range.
    #[error("invalid matching parameter `{name}` = {value}: {expected}")]
    InvalidParameter {
        /// The parameter.
        name: &'static str,
        /// The value given.
        value: f32,
        /// What is accepted.
        expected: &'static str,
    },
    /// The left and right images differ in size.
    #[error("stereo images differ in size: left {left_width}x{left_height}, right {right_width}x{right_height}")]
    ImageSizeMismatch {
        /// Left width.
        left_width: usize,
        /// Left height.
        left_height: usize,
        /// Right width.
        right_width: usize,
        /// Right height.
        right_height: usize,
    },
    /// A keypoint's octave has no entry in the scale tables.
    #[error("keypoint octave {octave} is outside the {levels} levels of the scale tables")]
    OctaveOutOfRange {
        /// The octave.
        octave: i32,
        /// Levels in the tables.
        levels: usize,
    },
    /// Building the level images or an OpenCV call failed.
    #[error(transparent)]
    Feature(#[from] FeatureError),
}

impl From<opencv::Error> for MatchError {
    fn from(e: opencv::Error) -> Self {
        MatchError::Feature(FeatureError::from(e))
    }
}
