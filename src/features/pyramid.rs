//! ORB-SLAM3's image pyramid: scale and sigma² tables, per-level feature quotas,
//! and the level images.

use opencv::core::{Mat, Size};

use super::{FeatureError, GrayImage, GrayImageView};

/// ORB-SLAM3's per-level tables, computed exactly as `ORBextractor`'s constructor does (in f32).
#[derive(Clone, Debug, PartialEq)]
pub struct ScaleTables {
    /// `mvScaleFactor`: 1, s, s², …
    pub scale_factors: Vec<f32>,
    /// `mvInvScaleFactor`: 1 / scale factor.
    pub inv_scale_factors: Vec<f32>,
    /// `mvLevelSigma2`: scale factor².
    pub level_sigma2: Vec<f32>,
    /// `mvInvLevelSigma2`: 1 / sigma².
    pub inv_level_sigma2: Vec<f32>,
    /// `mnFeaturesPerLevel`: the keypoint quota of each level.
    pub features_per_level: Vec<usize>,
}

impl ScaleTables {
    /// The tables for `n_levels` levels with ratio `scale_factor` and `n_features` keypoints in all.
    pub fn new(n_features: usize, scale_factor: f32, n_levels: usize) -> Self {
        let mut scale_factors = vec![1.0f32; n_levels];
        let mut level_sigma2 = vec![1.0f32; n_levels];
        for i in 1..n_levels {
            scale_factors[i] = scale_factors[i - 1] * scale_factor;
            level_sigma2[i] = scale_factors[i] * scale_factors[i];
        }
        let inv_scale_factors = scale_factors.iter().map(|s| 1.0 / s).collect();
        let inv_level_sigma2 = level_sigma2.iter().map(|s| 1.0 / s).collect();
        Self {
            features_per_level: features_per_level(n_features, scale_factor, n_levels),
            scale_factors,
            inv_scale_factors,
            level_sigma2,
            inv_level_sigma2,
        }
    }

    /// Number of levels.
    pub fn n_levels(&self) -> usize {
        self.scale_factors.len()
    }

    /// The scale factor of a keypoint's `octave`; `None` outside the
    /// pyramid.
    pub fn scale_at(&self, octave: i32) -> Option<f32> {
        usize::try_from(octave)
            .ok()
            .and_then(|o| self.scale_factors.get(o))
            .copied()
    }
}

/// ORB-SLAM3's `mnFeaturesPerLevel`: a geometric series over the levels, the
/// remainder on the last level.
fn features_per_level(n_features: usize, scale_factor: f32, n_levels: usize) -> Vec<usize> {
    let mut quotas = vec![0usize; n_levels];
    if n_levels == 0 {
        return quotas;
    }
    let factor = 1.0f32 / scale_factor;
    let mut desired =
        n_features as f32 * (1.0 - factor) / (1.0 - (factor as f64).powf(n_levels as f64) as f32);
    let mut sum = 0usize;
    for quota in quotas.iter_mut().take(n_levels - 1) {
        // cvRound rounds half away from zero for positive values.
        *quota = desired.round().max(0.0) as usize;
        sum += *quota;
        desired *= factor;
    }
    quotas[n_levels - 1] = n_features.saturating_sub(sum);
    quotas
}

/// What to add to `x·scale` to get the level-0 position of pixel `x` of a
/// level resized by `1/scale` with pixel-centre (bilinear) sampling:
/// `(x + ½)·scale − ½ − x·scale = ½(scale − 1)`. ORB-SLAM3 omits it, which
/// puts keypoints of level 7 (scale 3.58) 1.3 px up and left of their
/// true position; SLAM geometry adds it back ([`crate::tracking::Frame::new`]).
pub fn level_to_base_offset(scale: f32) -> f32 {
    0.5 * (scale - 1.0)
}

/// The level images: level 0 is the input, level i is level i-1 resized by
/// 1/scale_factor with bilinear interpolation (as ORB-SLAM3's `ComputePyramid`).
pub fn build_pyramid(
    image: GrayImageView<'_>,
    tables: &ScaleTables,
) -> Result<Vec<GrayImage>, FeatureError> {
    let mut levels = Vec::with_capacity(tables.n_levels());
    levels.push(image.to_owned_image());
    for level in 1..tables.n_levels() {
        let inv = tables.inv_scale_factors[level];
        let width = (image.width() as f32 * inv).round() as i32;
        let height = (image.height() as f32 * inv).round() as i32;
        if width < 1 || height < 1 {
            break;
        }
        let prev = levels[level - 1].to_mat()?;
        let mut resized = Mat::default();
        opencv::imgproc::resize(
            &prev,
            &mut resized,
            Size::new(width, height),
            0.0,
            0.0,
            opencv::imgproc::INTER_LINEAR,
        )?;
        levels.push(GrayImage::from_mat(&resized)?);
    }
    Ok(levels)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_match_orb_slam3_formulas() {
        let t = ScaleTables::new(1000, 1.2, 8);
        assert_eq!(t.scale_factors.len(), 8);
        let mut s = 1.0f32;
        for i in 0..8 {
            assert_eq!(t.scale_factors[i], s);
            assert_eq!(t.level_sigma2[i], s * s);
            assert_eq!(t.inv_scale_factors[i], 1.0 / s);
            assert_eq!(t.inv_level_sigma2[i], 1.0 / (s * s));
            s *= 1.2;
        }
        // ORB-SLAM3 with nfeatures = 1000, 1.2, 8 levels.
        assert_eq!(
            t.features_per_level,
            vec![217, 181, 151, 126, 105, 87, 73, 60]
        );
        assert_eq!(t.features_per_level.iter().sum::<usize>(), 1000);
    }

    #[test]
    fn single_level_takes_everything() {
        let t = ScaleTables::new(1234, 1.2, 1);
        assert_eq!(t.features_per_level, vec![1234]);
        assert_eq!(t.scale_factors, vec![1.0]);
    }
}
