//! The ORB extractor: ORB-SLAM3's `ORBextractor::operator()`.

use std::time::Instant;

use super::describe::describe;
use super::fast_cells::{detect_fast_in_cells, SearchRegion};
use super::octree::distribute_octree;
use super::OrbConfig;
use crate::features::descriptor_set::DescriptorSet;
use crate::features::frontend::{FeatureExtractor, FrameFeatures};
use crate::features::orientation::{CircularPatch, PATCH_SIZE};
use crate::features::pyramid::{build_pyramid, ScaleTables};
use crate::features::{FeatureError, GrayImageView, Keypoint, StageTimings, MIN_IMAGE_SIDE};

/// ORB keypoints and 256-bit descriptors with ORB-SLAM3's distribution: per
/// level quotas, FAST on cells, octree selection, intensity-centroid angle.
/// Deterministic: the same image gives the same output.
#[derive(Debug)]
pub struct OrbExtractor {
    config: OrbConfig,
    tables: ScaleTables,
    patch: CircularPatch,
}

impl OrbExtractor {
    /// Validates the config and builds the scale tables.
    pub fn new(config: OrbConfig) -> Result<Self, FeatureError> {
        config.validate()?;
        Ok(Self {
            tables: ScaleTables::new(config.n_features, config.scale_factor, config.n_levels),
            config,
            patch: CircularPatch::new(),
        })
    }

    /// The configuration in use.
    pub fn config(&self) -> &OrbConfig {
        &self.config
    }

    fn detect_level(
        &self,
        level: usize,
        image: GrayImageView<'_>,
        mat: &opencv::core::Mat,
        out: &mut Vec<Keypoint>,
    ) -> Result<(), FeatureError> {
        let region = SearchRegion::for_level(image.width() as i32, image.height() as i32);
        let corners = detect_fast_in_cells(
            mat,
            region,
            self.config.ini_th_fast,
            self.config.min_th_fast,
        )?;
        let kept = distribute_octree(
            &corners,
            region.width(),
            region.height(),
            self.tables.features_per_level[level],
        );
        let scale = self.tables.scale_factors[level];
        out.extend(kept.into_iter().map(|i| {
            let c = corners[i];
            let (x, y) = (c.x + region.min_x as f32, c.y + region.min_y as f32);
            Keypoint {
                x: x * scale,
                y: y * scale,
                size: PATCH_SIZE as f32 * scale,
                angle: self.patch.angle(image, x, y),
                response: c.response,
                octave: level as i32,
            }
        }));
        Ok(())
    }
}

impl FeatureExtractor for OrbExtractor {
    fn extract(&mut self, image: GrayImageView<'_>) -> Result<FrameFeatures, FeatureError> {
        let (width, height) = (image.width(), image.height());
        if width < MIN_IMAGE_SIDE || height < MIN_IMAGE_SIDE {
            return Err(FeatureError::ImageTooSmall {
                width,
                height,
                min_side: MIN_IMAGE_SIDE,
            });
        }
        let start = Instant::now();
        let pyramid = build_pyramid(image, &self.tables)?;
        let mut keypoints = Vec::with_capacity(self.config.n_features + 32);
        let mut level0 = None;
        for (level, level_image) in pyramid.iter().enumerate() {
            let mat = level_image.to_mat()?;
            self.detect_level(level, level_image.view(), &mat, &mut keypoints)?;
            if level == 0 {
                level0 = Some(mat);
            }
        }
        let detect_ms = start.elapsed().as_secs_f64() * 1e3;
        let t = Instant::now();
        let descriptors = match &level0 {
            Some(mat) => describe(
                mat,
                &keypoints,
                self.config.scale_factor,
                self.config.n_levels,
            )?,
            None => Vec::new(),
        };
        let describe_ms = t.elapsed().as_secs_f64() * 1e3;
        Ok(FrameFeatures {
            keypoints,
            descriptors: DescriptorSet::Binary { data: descriptors },
            timings: StageTimings {
                decode_nms_ms: detect_ms,
                descriptors_ms: describe_ms,
                total_ms: detect_ms + describe_ms,
                ..StageTimings::default()
            },
        })
    }

    fn scale_tables(&self) -> &ScaleTables {
        &self.tables
    }

    fn descriptor_kind(&self) -> crate::features::DescriptorKind {
        crate::features::DescriptorKind::Binary
    }

    fn name(&self) -> &str {
        "orb"
    }
}
