//! Threshold, non-maximum suppression and border removal on the dense score map.

use ndarray::ArrayView2;

use super::anms::Candidate;

/// Where candidates may lie: `[border, width - border) x [border, height - border)`
/// of the real (unpadded) image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ValidRegion {
    /// Real image width in pixels.
    pub width: usize,
    /// Real image height in pixels.
    pub height: usize,
    /// Pixels removed at each border.
    pub border: usize,
}

/// Finds every local maximum of `adjust(x, y, score)` above `threshold` in a
/// (2r+1)² window, inside the valid region. `adjust` lets a filter lower
/// scores (it must never raise them); use `|_, _, s| s` for plain NMS.
///
/// Ties between equal scores go to the first pixel in raster order, so each
/// plateau yields one candidate. The candidate's `score` is the raw network
/// score (the adjustment only decides which pixels survive). A NaN score is
/// never a candidate and suppresses nothing.
///
/// The window is clipped to the map, `adjust` is only called on neighbours
/// whose raw score could beat the pixel's, and a pixel's 3×3 neighbourhood
/// is checked before its whole window, so that only the 3×3 maxima pay for
/// a large radius.
pub fn nms_candidates(
    scores: ArrayView2<'_, f32>,
    adjust: impl Fn(usize, usize, f32) -> f32,
    threshold: f32,
    radius: usize,
    region: ValidRegion,
) -> Vec<Candidate> {
    let (rows, cols) = scores.dim();
    let x_end = region.width.min(cols).saturating_sub(region.border);
    let y_end = region.height.min(rows).saturating_sub(region.border);
    let mut out = Vec::new();
    if x_end <= region.border || y_end <= region.border {
        return out;
    }
    // Row-major and contiguous (a copy only when the caller's view is not).
    let contiguous = scores.as_standard_layout();
    let Some(values) = contiguous.as_slice() else {
        debug_assert!(false, "a standard-layout array is a slice");
        return out;
    };
    let survivors = SurvivingScores {
        values,
        rows,
        cols,
        adjust,
        threshold,
    };
    for y in region.border..y_end {
        for x in region.border..x_end {
            let s = survivors.at(x, y);
            if s == f32::NEG_INFINITY {
                continue;
            }
            if survivors.is_beaten_within(x, y, s, radius.min(1))
                || (radius > 1 && survivors.is_beaten_within(x, y, s, radius))
            {
                continue;
            }
            out.push(Candidate {
                x: x as f32,
                y: y as f32,
                score: values[y * cols + x],
            });
        }
    }
    out
}

/// The adjusted scores of the pixels that can win or suppress (adjusted
/// score above the threshold); every other pixel reads `-inf`. A pixel at or
/// below the threshold can neither be a maximum nor beat one that is above
/// it, so `adjust` is only called above the threshold.
struct SurvivingScores<'a, F> {
    /// The raw scores, row-major.
    values: &'a [f32],
    rows: usize,
    cols: usize,
    adjust: F,
    threshold: f32,
}

impl<F: Fn(usize, usize, f32) -> f32> SurvivingScores<'_, F> {
    fn at(&self, x: usize, y: usize) -> f32 {
        let raw = self.values[y * self.cols + x];
        if raw > self.threshold {
            let s = (self.adjust)(x, y, raw);
            if s > self.threshold {
                return s;
            }
        }
        f32::NEG_INFINITY
    }

    /// Whether a pixel of the (2r+1)² window around (x, y), clipped to the
    /// map, beats score `s` at (x, y): strictly greater, or equal and
    /// earlier in raster order.
    fn is_beaten_within(&self, x: usize, y: usize, s: f32, r: usize) -> bool {
        let (x0, x1) = (x.saturating_sub(r), (x + r + 1).min(self.cols));
        let (y0, y1) = (y.saturating_sub(r), (y + r + 1).min(self.rows));
        for ny in y0..y1 {
            let row = &self.values[ny * self.cols + x0..ny * self.cols + x1];
            for (nx, &raw) in (x0..x1).zip(row) {
                // Cheap rejection before the adjustment: a neighbour at or
                // below `s` in raw score cannot beat `s` after it.
                if !(raw > s || (raw == s && (ny, nx) < (y, x))) {
                    continue;
                }
                let n = self.at(nx, ny);
                let earlier = ny < y || (ny == y && nx < x);
                if n > s || (n == s && earlier) {
                    return true;
                }
            }
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array2;

    /// The definition, written out: every pixel of the region whose adjusted
    /// score is above `thr` and that no pixel of its window beats (greater,
    /// or equal and earlier in raster order). NaN compares false both ways.
    fn brute_force_adjusted(
        scores: &Array2<f32>,
        adjust: impl Fn(usize, usize, f32) -> f32,
        thr: f32,
        r: usize,
        region: ValidRegion,
    ) -> Vec<(usize, usize)> {
        let (rows, cols) = scores.dim();
        let mut out = vec![];
        for y in region.border..region.height - region.border {
            for x in region.border..region.width - region.border {
                let s = adjust(x, y, scores[[y, x]]);
                if s.is_nan() || s <= thr {
                    continue;
                }
                let mut ok = true;
                for ny in y.saturating_sub(r)..(y + r + 1).min(rows) {
                    for nx in x.saturating_sub(r)..(x + r + 1).min(cols) {
                        let n = adjust(nx, ny, scores[[ny, nx]]);
                        let earlier = (ny, nx) < (y, x);
                        if (ny, nx) != (y, x) && (n > s || (n == s && earlier)) {
                            ok = false;
                        }
                    }
                }
                if ok {
                    out.push((x, y));
                }
            }
        }
        out
    }

    fn brute_force(
        scores: &Array2<f32>,
        thr: f32,
        r: usize,
        region: ValidRegion,
    ) -> Vec<(usize, usize)> {
        brute_force_adjusted(scores, |_, _, s| s, thr, r, region)
    }

    #[test]
    fn matches_brute_force_on_random_maps_with_ties() {
        let mut state = 12345u64;
        for trial in 0..20 {
            let (rows, cols) = (40 + trial, 56 + 2 * trial);
            let scores = Array2::from_shape_fn((rows, cols), |_| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((state >> 33) % 16) as f32 / 16.0 // coarse values: many ties
            });
            let region = ValidRegion {
                width: cols,
                height: rows,
                border: 3,
            };
            let r = 1 + trial % 4;
            let got: Vec<_> = nms_candidates(scores.view(), |_, _, s| s, 0.2, r, region)
                .iter()
                .map(|c| (c.x as usize, c.y as usize))
                .collect();
            assert_eq!(got, brute_force(&scores, 0.2, r, region), "trial {trial}");
        }
    }

    #[test]
    fn border_and_padding_are_excluded() {
        let mut scores = Array2::<f32>::zeros((32, 32));
        scores[[2, 2]] = 0.9; // inside the border
        scores[[16, 16]] = 0.8;
        scores[[16, 29]] = 0.7; // beyond the real width 28 (padding)
        let region = ValidRegion {
            width: 28,
            height: 32,
            border: 4,
        };
        let got = nms_candidates(scores.view(), |_, _, s| s, 0.1, 2, region);
        assert_eq!(
            got,
            vec![Candidate {
                x: 16.0,
                y: 16.0,
                score: 0.8
            }]
        );
    }

    #[test]
    fn matches_brute_force_with_large_radii_an_adjustment_and_nan() {
        let mut state = 987654321u64;
        let mut maxima = 0;
        let mut next = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 33) as u32
        };
        for trial in 0..24 {
            let (rows, cols) = (16 + (next() % 50) as usize, 16 + (next() % 50) as usize);
            let mut scores = Array2::from_shape_fn((rows, cols), |_| (next() % 32) as f32 / 32.0);
            for _ in 0..3 {
                let (y, x) = ((next() as usize) % rows, (next() as usize) % cols);
                scores[[y, x]] = f32::NAN;
            }
            let region = ValidRegion {
                width: cols - (trial % 3),
                height: rows,
                border: trial % 5,
            };
            // Lowers every score in the columns divisible by 3, as a lattice mask would.
            let adjust = |x: usize, _: usize, s: f32| if x.is_multiple_of(3) { s * 0.5 } else { s };
            let r = [0, 1, 2, 5, 17, 64][trial % 6];
            // Odd trials pass a column-major view of the same map.
            let transposed = scores.t().to_owned();
            let view = if trial % 2 == 1 {
                transposed.t()
            } else {
                scores.view()
            };
            let got: Vec<_> = nms_candidates(view, adjust, 0.3, r, region)
                .iter()
                .map(|c| (c.x as usize, c.y as usize))
                .collect();
            let want = brute_force_adjusted(&scores, adjust, 0.3, r, region);
            assert_eq!(got, want, "trial {trial}, radius {r}");
            maxima += want.len();
        }
        assert!(maxima > 100, "only {maxima} maxima compared");
    }
}
