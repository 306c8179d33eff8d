//! Feature extraction: SuperPoint via ONNX Runtime, NMS, the periodic-artefact
//! filter, exposure normalisation, ANMS, descriptor sampling, the ORB-SLAM3 scale pyramid, and ORB.

pub mod anms;
mod config;
mod cuda_provider;
pub mod descriptor_set;
pub mod descriptors;
mod device;
mod distance_thresholds;
pub mod draw;
mod error;
pub mod exposure;
mod extractor;
pub mod frontend;
mod image;
mod inference;
mod keypoint;
mod local_contrast;
pub mod model;
pub mod nms;
pub mod orb;
pub mod orientation;
pub mod periodic;
pub mod pyramid;
pub mod runtime;
pub mod sign_bits;

pub use config::{
    default_model_path, threads_per_extractor, AnmsMethod, ExtractorConfig, PeriodicFilterConfig,
};
pub use descriptor_set::{DescriptorKind, DescriptorRef, DescriptorSet};
pub use device::Device;
pub use distance_thresholds::DistanceThresholds;
pub use error::FeatureError;
pub use exposure::{ExposureConfig, ExposureMode};
pub use extractor::{PeriodicFilterReport, SuperPointExtractor};
pub use frontend::{FeatureExtractor, FrameFeatures};
pub use image::{GrayImage, GrayImageView, MAX_IMAGE_SIDE, MIN_IMAGE_SIDE};
pub use inference::{int8_sums_saturate, models_dir, ModelWeights, Precision, MODELS_DIR_VARIABLE};
pub use keypoint::{Features, Keypoint, StageTimings};
pub use orb::{OrbConfig, OrbExtractor};
