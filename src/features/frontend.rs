//! One interface over the feature extractors (SuperPoint with or without ANMS,
//! ORB), so that the SLAM front end does not care which one runs.

use super::descriptor_set::{DescriptorKind, DescriptorSet};
use super::pyramid::ScaleTables;
use super::{
    DistanceThresholds, FeatureError, Features, GrayImageView, Keypoint, StageTimings,
    SuperPointExtractor,
};

/// Keypoints and their descriptors (of either kind) for one image.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameFeatures {
    /// Keypoints in level-0 pixels, with `octave` set.
    pub keypoints: Vec<Keypoint>,
    /// One descriptor row per keypoint.
    pub descriptors: DescriptorSet,
    /// Time per stage (extractors without a network leave the network stages at 0).
    pub timings: StageTimings,
}

impl FrameFeatures {
    /// Number of keypoints.
    pub fn len(&self) -> usize {
        self.keypoints.len()
    }

    /// True when there is no keypoint.
    pub fn is_empty(&self) -> bool {
        self.keypoints.is_empty()
    }
}

impl From<Features> for FrameFeatures {
    fn from(features: Features) -> Self {
        Self {
            keypoints: features.keypoints,
            descriptors: DescriptorSet::Float {
                dim: features.descriptor_len,
                data: features.descriptors,
            },
            timings: features.timings,
        }
    }
}

/// A feature extractor: image in, keypoints and descriptors out, with
/// ORB-SLAM3's scale tables describing the octaves it reports.
pub trait FeatureExtractor: Send {
    /// Extracts keypoints (level-0 coordinates) and descriptors from a gray image.
    fn extract(&mut self, image: GrayImageView<'_>) -> Result<FrameFeatures, FeatureError>;
    /// The scale and sigma² tables the keypoints' `octave` refers to.
    fn scale_tables(&self) -> &ScaleTables;
    /// A short name for logs and reports, e.g. `superpoint+kdtree` or `orb`.
    fn name(&self) -> &str;
    /// What its descriptors are: this picks the matching metric and
    /// thresholds (Hamming for binary, L2 for float).
    fn descriptor_kind(&self) -> DescriptorKind;
    /// ORB-SLAM3's `TH_LOW` / `TH_HIGH` for its descriptors: the kind's
    /// default unless the extractor knows better (a SuperPoint model may
    /// name its own). Frames and keyframes carry what their extractor said.
    fn distance_thresholds(&self) -> DistanceThresholds {
        DistanceThresholds::for_kind(self.descriptor_kind())
    }
    /// The period, in level pixels, of a lattice the descriptors repeat
    /// (SuperPoint's 8-px descriptor cell: a candidate one cell off can
    /// look as good as the truth); `None` when there is none (ORB). Stereo
    /// matching guards against it.
    fn descriptor_cell(&self) -> Option<f32> {
        None
    }
    /// How it runs, for reports: e.g. `int8 on cpu, 2 levels`.
    fn inference_summary(&self) -> String {
        format!("{} levels", self.scale_tables().n_levels())
    }
}

impl FeatureExtractor for SuperPointExtractor {
    fn extract(&mut self, image: GrayImageView<'_>) -> Result<FrameFeatures, FeatureError> {
        SuperPointExtractor::extract(self, image).map(FrameFeatures::from)
    }

    fn scale_tables(&self) -> &ScaleTables {
        SuperPointExtractor::scale_tables(self)
    }

    fn descriptor_kind(&self) -> DescriptorKind {
        DescriptorKind::Float {
            dim: self.descriptor_len(),
        }
    }

    fn descriptor_cell(&self) -> Option<f32> {
        Some(super::model::CELL as f32)
    }

    fn distance_thresholds(&self) -> DistanceThresholds {
        SuperPointExtractor::distance_thresholds(self)
    }

    fn name(&self) -> &str {
        match self.config().anms {
            super::AnmsMethod::Kdtree => "superpoint+anms-kdtree",
            super::AnmsMethod::Ssc => "superpoint+anms-ssc",
            super::AnmsMethod::None => "superpoint",
        }
    }

    fn inference_summary(&self) -> String {
        // A model given by path is used whatever the precision says: name it.
        let network = match &self.config().model_path {
            Some(path) => match super::ModelWeights::from_name(path) {
                Some(weights) => format!("{weights} model {}", self.config().precision),
                None => format!("model {}", path.display()),
            },
            None => self.config().precision.to_string(),
        };
        format!(
            "{network} on {}, {} levels",
            self.device(),
            self.scale_tables().n_levels()
        )
    }
}
