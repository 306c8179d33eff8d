//! How a Rust error becomes a Python exception: one function per error
//! family, each naming the exception class a Python user would catch.

use pyo3::exceptions::{PyFileNotFoundError, PyRuntimeError, PyValueError};
use pyo3::PyErr;
use spslam::features::FeatureError;

pyo3::create_exception!(
    spslam,
    SpslamError,
    PyRuntimeError,
    "An spslam operation failed; the message is the Rust error's."
);

/// An extractor error: a missing model or library is `FileNotFoundError`,
/// a bad setting or image is `ValueError`, anything else `SpslamError`.
pub fn feature_error(e: FeatureError) -> PyErr {
    let message = e.to_string();
    match e {
        FeatureError::ModelNotFound { .. } | FeatureError::RuntimeLibrary { .. } => {
            PyFileNotFoundError::new_err(message)
        }
        FeatureError::InvalidConfig { .. }
        | FeatureError::EmptyImage { .. }
        | FeatureError::ImageTooLarge { .. }
        | FeatureError::ImageTooSmall { .. }
        | FeatureError::StrideTooSmall { .. }
        | FeatureError::BufferTooSmall { .. }
        | FeatureError::UnsupportedImageType(_) => PyValueError::new_err(message),
        _ => SpslamError::new_err(message),
    }
}

/// A matching error (different descriptor kinds, a bad parameter): `ValueError`.
pub fn match_error(e: spslam::matching::MatchError) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// A metrics error: a file that cannot be read is `FileNotFoundError` /
/// `SpslamError`; mismatched or too short trajectories are `ValueError`.
pub fn eval_error(e: spslam::eval::EvalError) -> PyErr {
    use spslam::eval::EvalError;
    let message = e.to_string();
    match e {
        EvalError::Io { ref source, .. } if source.kind() == std::io::ErrorKind::NotFound => {
            PyFileNotFoundError::new_err(message)
        }
        EvalError::Io { .. } => SpslamError::new_err(message),
        _ => PyValueError::new_err(message),
    }
}
