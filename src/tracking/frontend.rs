//! Frame construction by sensor: the extractors (left and right in
//! parallel for stereo), then the keypoints' depths: stereo matching along
//! rows, the depth image (RGB-D), or none (monocular); the optional depth
//! filter.

use std::sync::Arc;
use std::time::Instant;

use crate::camera::{CameraRig, DepthImage, Sensor};
use crate::features::pyramid::ScaleTables;
use crate::features::{FeatureExtractor, FrameFeatures, GrayImageView};
use crate::map::StereoMeasurement;
use crate::matching::{
    match_stereo, DistanceThresholds, PeriodicGuard, StereoImages, StereoParams,
};

use super::frame::Frame;
use super::image_rotation::SmallBlurryImage;
use crate::error::{MapContext, SlamError};

/// The images of one frame, by sensor.
#[derive(Debug, Clone, Copy)]
pub enum SensorImages<'a> {
    /// One image.
    Monocular(GrayImageView<'a>),
    /// A rectified pair.
    Stereo {
        /// Left image.
        left: GrayImageView<'a>,
        /// Right image.
        right: GrayImageView<'a>,
    },
    /// An image and its registered depth.
    Rgbd {
        /// The (gray) colour image.
        image: GrayImageView<'a>,
        /// Its depth, metres.
        depth: &'a DepthImage,
    },
}

impl<'a> SensorImages<'a> {
    /// The image keypoints are tracked in (the left one for stereo).
    pub fn left(&self) -> GrayImageView<'a> {
        match *self {
            Self::Monocular(image) | Self::Rgbd { image, .. } => image,
            Self::Stereo { left, .. } => left,
        }
    }

    /// The sensor these images come from.
    pub fn sensor(&self) -> Sensor {
        match self {
            Self::Monocular(_) => Sensor::Monocular,
            Self::Stereo { .. } => Sensor::Stereo,
            Self::Rgbd { .. } => Sensor::Rgbd,
        }
    }
}

/// The features of one frame, before its depths are found.
#[derive(Debug, Clone)]
pub struct SensorFeatures {
    /// Left (or only) image's keypoints and descriptors.
    pub left: FrameFeatures,
    /// Right image's, for stereo.
    pub right: Option<FrameFeatures>,
}

/// The extractors: one per image, so a stereo pair's run at once.
///
/// They can live apart from the rest of the system: a pipelined run
/// extracts frame t+1 on its own thread while frame t is tracked
/// ([`Frontend::into_parts`]).
pub struct Extractors {
    left: Box<dyn FeatureExtractor>,
    right: Option<Box<dyn FeatureExtractor>>,
}

impl Extractors {
    /// The left extractor and, for stereo, the right one (configured alike).
    pub fn new(left: Box<dyn FeatureExtractor>, right: Option<Box<dyn FeatureExtractor>>) -> Self {
        Self { left, right }
    }

    /// The extractor's name, for reports.
    pub fn name(&self) -> &str {
        self.left.name()
    }

    /// Extracts the frame's features (a stereo pair's in parallel).
    pub fn extract(
        &mut self,
        index: usize,
        images: SensorImages<'_>,
    ) -> Result<SensorFeatures, SlamError> {
        let features = |r: Result<FrameFeatures, _>| {
            r.map_err(|source| SlamError::Features {
                frame: index,
                source,
            })
        };
        let (left_image, right_image) = match images {
            SensorImages::Stereo { left, right } => (left, right),
            SensorImages::Rgbd { image, depth } => {
                if (image.width(), image.height()) != (depth.width(), depth.height()) {
                    return Err(SlamError::DepthSizeMismatch {
                        frame: index,
                        image_width: image.width(),
                        image_height: image.height(),
                        depth_width: depth.width(),
                        depth_height: depth.height(),
                    });
                }
                let left = features(self.left.extract(image))?;
                return Ok(SensorFeatures { left, right: None });
            }
            SensorImages::Monocular(image) => {
                let left = features(self.left.extract(image))?;
                return Ok(SensorFeatures { left, right: None });
            }
        };
        if (left_image.width(), left_image.height()) != (right_image.width(), right_image.height())
        {
            return Err(SlamError::ImageSizeMismatch {
                frame: index,
                left_width: left_image.width(),
                left_height: left_image.height(),
                right_width: right_image.width(),
                right_height: right_image.height(),
            });
        }
        let left_extractor = &mut self.left;
        let Some(right_extractor) = self.right.as_mut() else {
            return Err(SlamError::SensorMismatch {
                frame: index,
                expected: Sensor::Monocular,
                found: Sensor::Stereo,
            });
        };
        let (left, right) = std::thread::scope(|scope| {
            let right_job = scope.spawn(move || right_extractor.extract(right_image));
            let left = left_extractor.extract(left_image);
            let right = right_job.join().unwrap_or_else(|_| {
                Err(crate::features::FeatureError::InvalidConfig {
                    name: "right extractor",
                    value: "panicked".into(),
                    expected: "no panic",
                })
            });
            (left, right)
        });
        Ok(SensorFeatures {
            left: features(left)?,
            right: Some(features(right)?),
        })
    }
}

/// Builds frames from extracted features: the keypoints' depths by
/// sensor, with the extractor's scale tables and descriptor thresholds.
pub struct FrameBuilder {
    stereo: StereoParams,
    scales: ScaleTables,
    name: String,
    sensor: Sensor,
    descriptor_cell: Option<f32>,
    distance_thresholds: DistanceThresholds,
}

/// The extractors and the frame builder, made together from the
/// extractors and a rig; [`SlamSystem`](crate::system::SlamSystem) keeps
/// them apart ([`Self::into_parts`]).
pub struct Frontend {
    extractors: Extractors,
    builder: FrameBuilder,
}

impl Frontend {
    /// A stereo front end for `rig`: `left` and `right` must be configured
    /// alike. The matching thresholds come from the extractor's descriptor
    /// kind (L2 for float, Hamming for binary), and the periodic guards
    /// from its descriptor cell.
    pub fn new(
        left: Box<dyn FeatureExtractor>,
        right: Box<dyn FeatureExtractor>,
        rig: &CameraRig,
    ) -> Self {
        let builder = FrameBuilder::new(left.as_ref(), rig);
        Self {
            extractors: Extractors::new(left, Some(right)),
            builder,
        }
    }

    /// A single-camera front end (monocular or RGB-D, as `rig.sensor` says;
    /// a stereo rig gets an error: it needs [`Self::new`]).
    pub fn single(
        extractor: Box<dyn FeatureExtractor>,
        rig: &CameraRig,
    ) -> Result<Self, SlamError> {
        if rig.sensor == Sensor::Stereo {
            return Err(SlamError::InvalidCamera {
                reason: "a stereo rig needs two extractors (Frontend::new)".into(),
            });
        }
        let builder = FrameBuilder::new(extractor.as_ref(), rig);
        Ok(Self {
            extractors: Extractors::new(extractor, None),
            builder,
        })
    }

    /// The extractors and the frame builder, apart.
    pub fn into_parts(self) -> (Extractors, FrameBuilder) {
        (self.extractors, self.builder)
    }
}

impl FrameBuilder {
    fn new(extractor: &dyn FeatureExtractor, rig: &CameraRig) -> Self {
        let thresholds = extractor.distance_thresholds();
        let periodic = extractor.descriptor_cell().map(PeriodicGuard::for_cell);
        let stereo = StereoParams::new(
            rig.camera.bf as f32,
            rig.baseline as f32,
            thresholds.stereo(),
            periodic,
        );
        Self {
            stereo,
            scales: extractor.scale_tables().clone(),
            name: extractor.name().to_string(),
            sensor: rig.sensor,
            descriptor_cell: extractor.descriptor_cell(),
            distance_thresholds: thresholds,
        }
    }

    /// The extractor's name, for reports.
    pub fn extractor_name(&self) -> &str {
        &self.name
    }

    /// Builds the frame from its features: stereo matching along rows,
    /// depths read from the depth image (RGB-D), or none (monocular); the
    /// depth filter applied. Returns it with the milliseconds spent.
    pub fn build_frame(
        &self,
        index: usize,
        timestamp: f64,
        features: SensorFeatures,
        images: SensorImages<'_>,
        rig: &CameraRig,
    ) -> Result<(Frame, f64), SlamError> {
        let start = Instant::now();
        if images.sensor() != self.sensor {
            return Err(SlamError::SensorMismatch {
                frame: index,
                expected: self.sensor,
                found: images.sensor(),
            });
        }
        let depths = match images {
            SensorImages::Stereo { left, right } => {
                let Some(right_features) = features.right.as_ref() else {
                    return Err(SlamError::SensorMismatch {
                        frame: index,
                        expected: Sensor::Stereo,
                        found: Sensor::Monocular,
                    });
                };
                let outcome = match_stereo(
                    &features.left,
                    right_features,
                    StereoImages { left, right },
                    &self.scales,
                    &self.stereo,
                )
                .in_stage("stereo")?;
                tracing::debug!(frame = index, rejections = ?outcome.rejections, "stereo matching");
                outcome
                    .matches
                    .iter()
                    .map(|m| {
                        m.map(|m| StereoMeasurement {
                            right_u: m.right_u,
                            depth: m.depth,
                        })
                    })
                    .collect()
            }
            SensorImages::Rgbd { depth, .. } => depths_from_image(&features.left, depth, rig),
            SensorImages::Monocular(_) => vec![None; features.left.len()],
        };
        let stereo: Vec<Option<StereoMeasurement>> = depths
            .into_iter()
            .map(|m: Option<StereoMeasurement>| {
                m.filter(|m| rig.max_depth.is_none_or(|d| f64::from(m.depth) <= d))
            })
            .collect();
        let mut frame = Frame::new(
            index,
            timestamp,
            features.left,
            stereo,
            self.scales.clone(),
            rig,
        );
        frame.descriptor_cell = self.descriptor_cell;
        frame.distance_thresholds = self.distance_thresholds;
        frame.thumbnail = SmallBlurryImage::new(images.left(), &rig.camera).map(Arc::new);
        Ok((frame, start.elapsed().as_secs_f64() * 1e3))
    }
}

/// ORB-SLAM3's `Frame::ComputeStereoFromRGBD`: each keypoint's depth from
/// the depth image at its (level-0) position, and the virtual right column
/// `u − bf/d`.
fn depths_from_image(
    features: &FrameFeatures,
    depth: &DepthImage,
    rig: &CameraRig,
) -> Vec<Option<StereoMeasurement>> {
    features
        .keypoints
        .iter()
        .map(|kp| {
            let d = depth.depth_at(kp.x, kp.y)?;
            Some(StereoMeasurement {
                right_u: kp.x - (rig.camera.bf / f64::from(d)) as f32,
                depth: d,
            })
        })
        .collect()
}
