//! Frame construction: left and right extraction in parallel, stereo
//! matching along rows, the optional depth filter.

use std::time::Instant;

use crate::features::pyramid::ScaleTables;
use crate::features::{FeatureExtractor, FrameFeatures, GrayImageView};
use crate::map::StereoMeasurement;
use crate::matching::{
    match_stereo, DistanceThresholds, PeriodicGuard, StereoImages, StereoParams,
};

use super::frame::Frame;
use crate::camera::StereoRig;
use crate::error::{MapContext, SlamError};

/// The features of one stereo pair, before stereo matching.
#[derive(Debug, Clone)]
pub struct StereoFeatures {
    /// Left image's keypoints and descriptors.
    pub left: FrameFeatures,
    /// Right image's.
    pub right: FrameFeatures,
}

/// The left and right extractors (one per image, so both run at once).
///
/// They can live apart from the rest of the system: a pipelined run
/// extracts frame t+1 on its own thread while frame t is tracked
/// ([`StereoFrontend::into_parts`]).
pub struct StereoExtractors {
    left: Box<dyn FeatureExtractor>,
    right: Box<dyn FeatureExtractor>,
}

impl StereoExtractors {
    /// Two extractors, configured alike.
    pub fn new(left: Box<dyn FeatureExtractor>, right: Box<dyn FeatureExtractor>) -> Self {
        Self { left, right }
    }

    /// The extractor's name, for reports.
    pub fn name(&self) -> &str {
        self.left.name()
    }

    /// Extracts the left and right images' features in parallel.
    pub fn extract(
        &mut self,
        index: usize,
        left_image: GrayImageView<'_>,
        right_image: GrayImageView<'_>,
    ) -> Result<StereoFeatures, SlamError> {
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
        let (left_extractor, right_extractor) = (&mut self.left, &mut self.right);
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
        let features = |r: Result<FrameFeatures, _>| {
            r.map_err(|source| SlamError::Features {
                frame: index,
                source,
            })
        };
        Ok(StereoFeatures {
            left: features(left)?,
            right: features(right)?,
        })
    }
}

/// Stereo matching along rows, with the extractor's scale tables and
/// descriptor thresholds.
pub struct StereoMatcher {
    stereo: StereoParams,
    scales: ScaleTables,
    name: String,
}

/// The two extractors and the stereo matcher, built together from one
/// extractor pair and a rig; [`StereoSlam`](crate::system::StereoSlam)
/// keeps them apart ([`Self::into_parts`]).
pub struct StereoFrontend {
    extractors: StereoExtractors,
    matcher: StereoMatcher,
}

impl StereoFrontend {
    /// A front end for `rig`. `left` and `right` must be configured alike;
    /// SuperPoint (float descriptors) gets its L2 thresholds and periodic
    /// guards, ORB its Hamming thresholds.
    pub fn new(
        left: Box<dyn FeatureExtractor>,
        right: Box<dyn FeatureExtractor>,
        rig: &StereoRig,
    ) -> Self {
        let kind_is_float = left.name().starts_with("superpoint");
        let thresholds = if kind_is_float {
            DistanceThresholds::SUPERPOINT_L2
        } else {
            DistanceThresholds::ORB_HAMMING
        };
        let periodic = kind_is_float.then_some(PeriodicGuard::SUPERPOINT);
        let stereo = StereoParams::new(
            rig.camera.bf as f32,
            rig.baseline as f32,
            thresholds.stereo(),
            periodic,
        );
        let matcher = StereoMatcher {
            stereo,
            scales: left.scale_tables().clone(),
            name: left.name().to_string(),
        };
        Self {
            extractors: StereoExtractors::new(left, right),
            matcher,
        }
    }

    /// The extractors and the matcher, apart.
    pub fn into_parts(self) -> (StereoExtractors, StereoMatcher) {
        (self.extractors, self.matcher)
    }
}

impl StereoMatcher {
    /// The extractor's name, for reports.
    pub fn extractor_name(&self) -> &str {
        &self.name
    }

    /// Matches extracted features along rows into a frame (the depth filter
    /// applied); returns it with the milliseconds spent.
    pub fn match_frame(
        &self,
        index: usize,
        timestamp: f64,
        features: StereoFeatures,
        (left_image, right_image): (GrayImageView<'_>, GrayImageView<'_>),
        rig: &StereoRig,
    ) -> Result<(Frame, f64), SlamError> {
        let start = Instant::now();
        let scales = self.scales.clone();
        let outcome = match_stereo(
            &features.left,
            &features.right,
            StereoImages {
                left: left_image,
                right: right_image,
            },
            &scales,
            &self.stereo,
        )
        .in_stage("stereo")?;
        tracing::debug!(frame = index, rejections = ?outcome.rejections, "stereo matching");
        let stereo: Vec<Option<StereoMeasurement>> = outcome
            .matches
            .iter()
            .map(|m| {
                m.filter(|m| rig.max_depth.is_none_or(|d| f64::from(m.depth) <= d))
                    .map(|m| StereoMeasurement {
                        right_u: m.right_u,
                        depth: m.depth,
                    })
            })
            .collect();
        let frame = Frame::new(index, timestamp, features.left, stereo, scales, rig);
        Ok((frame, start.elapsed().as_secs_f64() * 1e3))
    }
}
