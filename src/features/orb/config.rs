use crate::features::FeatureError;

/// ORB-SLAM3's extractor parameters (`ORBextractor.*` in its settings files).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OrbConfig {
    /// Keypoints over all levels (`nFeatures`).
    pub n_features: usize,
    /// Scale between levels (`scaleFactor`).
    pub scale_factor: f32,
    /// Pyramid levels (`nLevels`).
    pub n_levels: usize,
    /// FAST threshold tried first in each cell (`iniThFAST`).
    pub ini_th_fast: i32,
    /// FAST threshold used in a cell where the first finds nothing (`minThFAST`).
    pub min_th_fast: i32,
}

impl Default for OrbConfig {
    /// ORB-SLAM3's KITTI settings: 1000 features, scale 1.2, 8 levels, FAST 20 / 7.
    fn default() -> Self {
        Self {
            n_features: 1000,
            scale_factor: 1.2,
            n_levels: 8,
            ini_th_fast: 20,
            min_th_fast: 7,
        }
    }
}

impl OrbConfig {
    /// Checks every value; the error names the first one out of range.
    pub fn validate(&self) -> Result<(), FeatureError> {
        let bad = |name, value: String, expected| {
            Err(FeatureError::InvalidConfig {
                name,
                value,
                expected,
            })
        };
        if self.n_features == 0 || self.n_features > 1_000_000 {
            return bad(
                "n_features",
                self.n_features.to_string(),
                "between 1 and 1000000",
            );
        }
        if !(self.scale_factor.is_finite() && self.scale_factor > 1.0 && self.scale_factor <= 4.0) {
            return bad(
                "scale_factor",
                self.scale_factor.to_string(),
                "a number in (1, 4]",
            );
        }
        if self.n_levels == 0 || self.n_levels > 32 {
            return bad("n_levels", self.n_levels.to_string(), "between 1 and 32");
        }
        if !(1..=255).contains(&self.ini_th_fast) {
            return bad(
                "ini_th_fast",
                self.ini_th_fast.to_string(),
                "a FAST threshold in 1..=255",
            );
        }
        if !(1..=self.ini_th_fast).contains(&self.min_th_fast) {
            return bad(
                "min_th_fast",
                self.min_th_fast.to_string(),
                "a FAST threshold in 1..=ini_th_fast",
            );
        }
        Ok(())
    }
}
