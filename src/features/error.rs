use std::path::PathBuf;

/// Everything that can go wrong while configuring or running an extractor.
#[derive(Debug, thiserror::Error)]
pub enum FeatureError {
    /// The image has a zero width or height.
    #[error("image is empty ({width}x{height}); give an image with at least one pixel")]
    EmptyImage {
        /// Width in pixels.
        width: usize,
        /// Height in pixels.
        height: usize,
    },
    /// The image is larger than the extractor accepts.
    #[error("image is {width}x{height}; the largest accepted side is {max_side} px")]
    ImageTooLarge {
        /// Width in pixels.
        width: usize,
        /// Height in pixels.
        height: usize,
        /// The largest accepted width or height.
        max_side: usize,
    },
    /// The image is too small to hold one descriptor cell after the border is removed.
    #[error("image is {width}x{height}; it must be at least {min_side} px on each side")]
    ImageTooSmall {
        /// Width in pixels.
        width: usize,
        /// Height in pixels.
        height: usize,
        /// The smallest accepted width or height.
        min_side: usize,
    },
    /// The row stride is smaller than the width.
    #[error("row stride {stride} is smaller than the width {width}")]
    StrideTooSmall {
        /// Bytes per row given.
        stride: usize,
        /// Width in pixels.
        width: usize,
    },
    /// The pixel buffer is shorter than `stride * (height - 1) + width`.
    #[error("pixel buffer holds {actual} bytes; a {width}x{height} image with stride {stride} needs {required}")]
    BufferTooSmall {
        /// Bytes needed.
        required: usize,
        /// Bytes given.
        actual: usize,
        /// Width in pixels.
        width: usize,
        /// Height in pixels.
        height: usize,
        /// Bytes per row.
        stride: usize,
    },
    /// The image file could not be read or decoded.
    #[error("cannot read image {path}: {reason}")]
    ImageRead {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        reason: String,
    },
    /// The image has an unsupported pixel type.
    #[error("unsupported image type: {0}; give an 8-bit gray (or 8-bit colour) image")]
    UnsupportedImageType(String),
    /// A configuration value is out of range.
    #[error("invalid setting `{name}` = {value}: {expected}")]
    InvalidConfig {
        /// The setting's name.
        name: &'static str,
        /// The value given, as text.
        value: String,
        /// What is accepted.
        expected: &'static str,
    },
    /// The ONNX Runtime shared library could not be found or loaded.
    #[error("cannot load the ONNX Runtime library: {reason}. Run `make setup` (it puts libonnxruntime.so.1.31.1 under .deps/onnxruntime/), or set ORT_DYLIB_PATH or the config's ort_library_path")]
    RuntimeLibrary {
        /// What went wrong, including the paths tried.
        reason: String,
    },
    /// The model file is missing.
    #[error("SuperPoint model not found at {path}; run `make setup` to write models/superpoint.onnx and models/superpoint_int8.onnx, or pass --model / set SPSLAM_MODEL (fp32) or SPSLAM_MODEL_INT8 (int8)")]
    ModelNotFound {
        /// The path tried.
        path: PathBuf,
    },
    /// The model loaded but does not have the SuperPoint interface.
    #[error("model {path} does not have the SuperPoint interface: {reason}")]
    ModelInterface {
        /// The model file.
        path: PathBuf,
        /// What does not match.
        reason: String,
    },
    /// The requested device cannot run the network.
    #[error("cannot run SuperPoint on {device}: {reason}. For CUDA run `make setup-gpu` (it installs ONNX Runtime's GPU build and its CUDA libraries) and set ORT_DYLIB_PATH as it prints, on a machine with an NVIDIA GPU and driver; or choose --device cpu")]
    DeviceUnavailable {
        /// The device asked for.
        device: super::Device,
        /// What went wrong.
        reason: String,
    },
    /// ONNX Runtime failed while loading the model or running it.
    #[error("ONNX Runtime error: {0}")]
    Runtime(String),
    /// An OpenCV call failed.
    #[error("OpenCV error: {0}")]
    OpenCv(String),
}

impl From<opencv::Error> for FeatureError {
    fn from(e: opencv::Error) -> Self {
        FeatureError::OpenCv(e.to_string())
    }
}

impl From<ort::Error> for FeatureError {
    fn from(e: ort::Error) -> Self {
        FeatureError::Runtime(e.to_string())
    }
}
