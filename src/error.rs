//! Errors of the SLAM pipeline, shared by tracking, local mapping and the
//! system layer that drives them.

use crate::features::FeatureError;
use crate::map::MapError;
use crate::matching::MatchError;
use crate::optim::OptimError;

/// Something the SLAM pipeline could not do.
#[derive(Debug, thiserror::Error)]
pub enum SlamError {
    /// Feature extraction failed on a frame.
    #[error("feature extraction failed on frame {frame}: {source}")]
    Features {
        /// The frame's index in the sequence.
        frame: usize,
        /// What the extractor said.
        #[source]
        source: FeatureError,
    },
    /// An extractor could not be created (a missing model or runtime
    /// library, a bad setting).
    #[error("cannot create the extractor: {source}")]
    Extractor {
        /// What the extractor said.
        #[source]
        source: FeatureError,
    },
    /// The loop-closing codebook cannot be used with this extractor.
    #[error("cannot use the loop-closing codebook {}: {source} (train one with `spslam vocab train --format vlad`, or turn loop closing off)", path.display())]
    Codebook {
        /// The codebook file.
        path: std::path::PathBuf,
        /// What place recognition said.
        #[source]
        source: crate::place::PlaceError,
    },
    /// A matcher rejected its input.
    #[error("matching failed ({stage}): {source}")]
    Matching {
        /// Which step matched.
        stage: &'static str,
        /// What the matcher said.
        #[source]
        source: MatchError,
    },
    /// A map operation referred to something that is not there.
    #[error("map operation failed ({stage}): {source}")]
    Map {
        /// Which step changed the map.
        stage: &'static str,
        /// What the map said.
        #[source]
        source: MapError,
    },
    /// An optimisation rejected its problem.
    #[error("optimisation failed ({stage}): {source}")]
    Optimisation {
        /// Which optimisation.
        stage: &'static str,
        /// What the optimiser said.
        #[source]
        source: OptimError,
    },
    /// OpenCV failed (relocalisation's PnP).
    #[error("OpenCV failed in {stage}: {source}")]
    OpenCv {
        /// Which step called OpenCV.
        stage: &'static str,
        /// OpenCV's error.
        #[source]
        source: opencv::Error,
    },
    /// The camera settings cannot drive a stereo SLAM.
    #[error("invalid camera for stereo SLAM: {reason}")]
    InvalidCamera {
        /// What is wrong.
        reason: String,
    },
    /// An RGB-D frame's depth image differs in size from its image.
    #[error("frame {frame}: the image is {image_width}x{image_height}, its depth image {depth_width}x{depth_height}; depth must be registered to the image")]
    DepthSizeMismatch {
        /// Frame index.
        frame: usize,
        /// Image width.
        image_width: usize,
        /// Image height.
        image_height: usize,
        /// Depth width.
        depth_width: usize,
        /// Depth height.
        depth_height: usize,
    },
    /// A frame's images are not what the system's sensor takes.
    #[error("frame {frame}: the system runs a {expected} sensor but was given {found} images")]
    SensorMismatch {
        /// Frame index.
        frame: usize,
        /// The system's sensor.
        expected: crate::camera::Sensor,
        /// What the frame holds.
        found: crate::camera::Sensor,
    },
    /// The left and right images of a frame differ in size.
    #[error("frame {frame}: left image is {left_width}x{left_height}, right is {right_width}x{right_height}")]
    ImageSizeMismatch {
        /// The frame's index.
        frame: usize,
        /// Left width.
        left_width: usize,
        /// Left height.
        left_height: usize,
        /// Right width.
        right_width: usize,
        /// Right height.
        right_height: usize,
    },
    /// The shared map's lock was poisoned by a panicking thread.
    #[error("the shared map's lock is poisoned (a thread panicked while holding it)")]
    PoisonedMap,
    /// The keyframe database's lock was poisoned by a panicking thread
    /// (loop detection and relocalisation share it).
    #[error("the keyframe database's lock is poisoned (a thread panicked while holding it)")]
    PoisonedKeyframeDatabase,
    /// A map invariant was broken after a local-mapping step (checked in
    /// debug builds and tests, see `LocalMapper::check_invariants`).
    #[error("map invariant broken after {stage}: {source}")]
    MapInvariant {
        /// The step after which the check failed.
        stage: &'static str,
        /// What is inconsistent.
        #[source]
        source: crate::map::InvariantViolation,
    },
    /// A frame record refers to a map the atlas does not have.
    #[error("atlas map {map} does not exist")]
    UnknownAtlasMap {
        /// The map index.
        map: usize,
    },
    /// A worker thread (local mapping, loop closing, the global BA) could
    /// not start, or stopped unexpectedly (a panic keeps its message).
    #[error("the {name} thread stopped: {reason}")]
    Thread {
        /// The thread's name (`local-mapping`, `loop-closing`, `global-ba`).
        name: &'static str,
        /// What happened.
        reason: String,
    },
    /// Place recognition failed (global descriptor or keyframe database).
    #[error("place recognition failed ({stage}): {source}")]
    Place {
        /// Which step.
        stage: &'static str,
        /// What place recognition said.
        #[source]
        source: crate::place::PlaceError,
    },
    /// Saving or loading a map file failed.
    #[error(transparent)]
    Storage(#[from] crate::storage::StorageError),
    /// The extractors were handed to a pipeline thread
    /// ([`SlamSystem::detach_extractors`](crate::system::SlamSystem::detach_extractors)),
    /// so this system only tracks features extracted elsewhere.
    #[error("frame {frame}: the extractors run on a pipeline thread; give this system extracted features (process_features)")]
    ExtractorsDetached {
        /// The frame's index in the sequence.
        frame: usize,
    },
}

/// Wraps map errors with the step that caused them.
pub(crate) trait MapContext<T> {
    /// Names the step.
    fn in_stage(self, stage: &'static str) -> Result<T, SlamError>;
}

impl<T> MapContext<T> for Result<T, MapError> {
    fn in_stage(self, stage: &'static str) -> Result<T, SlamError> {
        self.map_err(|source| SlamError::Map { stage, source })
    }
}

impl<T> MapContext<T> for Result<T, MatchError> {
    fn in_stage(self, stage: &'static str) -> Result<T, SlamError> {
        self.map_err(|source| SlamError::Matching { stage, source })
    }
}

impl<T> MapContext<T> for Result<T, OptimError> {
    fn in_stage(self, stage: &'static str) -> Result<T, SlamError> {
        self.map_err(|source| SlamError::Optimisation { stage, source })
    }
}

impl<T> MapContext<T> for Result<T, crate::place::PlaceError> {
    fn in_stage(self, stage: &'static str) -> Result<T, SlamError> {
        self.map_err(|source| SlamError::Place { stage, source })
    }
}

impl<T> MapContext<T> for Result<T, opencv::Error> {
    fn in_stage(self, stage: &'static str) -> Result<T, SlamError> {
        self.map_err(|source| SlamError::OpenCv { stage, source })
    }
}

impl SlamError {
    /// [`SlamError::Thread`] for a thread `name` that panicked with
    /// `payload` (the panic's message kept).
    pub fn thread_panicked(name: &'static str, payload: &(dyn std::any::Any + Send)) -> Self {
        SlamError::Thread {
            name,
            reason: format!("it panicked: {}", panic_message(payload)),
        }
    }
}

impl From<crate::camera::InvalidCamera> for SlamError {
    fn from(e: crate::camera::InvalidCamera) -> Self {
        SlamError::InvalidCamera { reason: e.reason }
    }
}

/// The message of a caught panic's payload (`panic!` with a literal or a
/// formatted message), or `"no message"`. The crate's one helper for it:
/// worker threads, the C ABI and the CLI's pipeline all report panics
/// through it.
pub fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| (*s).to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "no message".into())
}
