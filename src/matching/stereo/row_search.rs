//! The descriptor search along a row: right keypoints indexed by row band,
//! the best candidate in the disparity range, the ratio test and the
//! descriptor half of the periodic guard.

use super::{StereoParams, StereoRejections};
use crate::features::pyramid::ScaleTables;
use crate::features::{FrameFeatures, Keypoint};
use crate::matching::BestTwo;

/// For each image row, the right keypoints whose band (±`factor`·scale rows
/// around them) covers it, as ORB-SLAM3's `vRowIndices`.
pub struct RowBands {
    rows: Vec<Vec<usize>>,
}

impl RowBands {
    /// Indexes the right keypoints for an image of `height` rows.
    pub fn new(keypoints: &[Keypoint], height: usize, tables: &ScaleTables, factor: f32) -> Self {
        let mut rows = vec![Vec::new(); height];
        for (i, kp) in keypoints.iter().enumerate() {
            let scale = tables
                .scale_factors
                .get(kp.octave.max(0) as usize)
                .copied()
                .unwrap_or(1.0);
            let r = factor * scale;
            let lo = (kp.y - r).floor().max(0.0) as usize;
            let hi = (kp.y + r).ceil();
            if hi < 0.0 {
                continue;
            }
            let hi = (hi as usize).min(height.saturating_sub(1));
            for row in rows.iter_mut().take(hi + 1).skip(lo) {
                row.push(i);
            }
        }
        Self { rows }
    }

    /// The right keypoints whose band covers row `y` (truncated, as ORB-SLAM3).
    pub fn at(&self, y: f32) -> &[usize] {
        if y < 0.0 {
            return &[];
        }
        self.rows.get(y as usize).map_or(&[], |v| v.as_slice())
    }
}

/// Why no right keypoint was chosen.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RowFailure {
    /// No candidate.
    NoCandidate,
    /// The best is above the distance threshold.
    Distance,
    /// Ratio test failed.
    Ratio,
    /// A near-best candidate one period away.
    Periodic,
}

impl RowFailure {
    /// Adds one to the matching counter.
    pub fn count(self, r: &mut StereoRejections) {
        match self {
            RowFailure::NoCandidate => r.no_candidate += 1,
            RowFailure::Distance => r.distance += 1,
            RowFailure::Ratio => r.ratio += 1,
            RowFailure::Periodic => r.periodic_descriptor += 1,
        }
    }
}

/// The chosen right keypoint.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RowCandidate {
    /// Right keypoint index.
    pub right_index: usize,
    /// Its descriptor distance.
    pub distance: f32,
}

/// The descriptor search of one stereo pair.
pub struct RowSearch<'a> {
    /// Left features.
    pub left: &'a FrameFeatures,
    /// Right features.
    pub right: &'a FrameFeatures,
    /// Right keypoints by row.
    pub bands: &'a RowBands,
    /// The parameters.
    pub params: &'a StereoParams,
}

impl RowSearch<'_> {
    /// The best right keypoint for left keypoint `i` (at scale `scale`):
    /// octave within ±1, column within the disparity range, then the
    /// distance, ratio and periodic tests.
    pub fn best_on_row(&self, i: usize, scale: f32) -> Result<RowCandidate, RowFailure> {
        let kp = self.left.keypoints[i];
        let min_u = kp.x - self.params.max_disparity();
        let max_u = kp.x - self.params.min_disparity;
        let mut best = BestTwo::default();
        let mut candidates: Vec<(usize, f32)> = Vec::new();
        for &j in self.bands.at(kp.y) {
            let r = self.right.keypoints[j];
            if r.octave < kp.octave - 1 || r.octave > kp.octave + 1 || r.x < min_u || r.x > max_u {
                continue;
            }
            let Some(d) = self
                .left
                .descriptors
                .distance(i, &self.right.descriptors, j)
            else {
                continue;
            };
            best.offer(j, d);
            candidates.push((j, d));
        }
        let Some((j, d)) = best.best else {
            return Err(RowFailure::NoCandidate);
        };
        if d > self.params.max_distance {
            return Err(RowFailure::Distance);
        }
        if best
            .accept(self.params.max_distance, self.params.ratio)
            .is_none()
        {
            return Err(RowFailure::Ratio);
        }
        if let Some(guard) = self.params.periodic {
            let best_u = self.right.keypoints[j].x;
            let period = guard.period * scale;
            let tol = guard.tolerance * scale;
            let periodic = candidates.iter().any(|&(k, dk)| {
                k != j
                    && ((self.right.keypoints[k].x - best_u).abs() - period).abs() <= tol
                    && d >= guard.descriptor_ratio * dk
            });
            if periodic {
                return Err(RowFailure::Periodic);
            }
        }
        Ok(RowCandidate {
            right_index: j,
            distance: d,
        })
    }
}
