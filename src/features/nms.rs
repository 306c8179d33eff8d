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
/// score (the adjustment only decides which pixels survive).
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
    let adjusted = |x: usize, y: usize| adjust(x, y, scores[[y, x]]);
    let r = radius as isize;
    for y in region.border..y_end {
        let row = scores.row(y);
        for x in region.border..x_end {
            let raw = row[x];
            if raw <= threshold {
                continue;
            }
            let s = adjust(x, y, raw);
            if s <= threshold {
                continue;
            }
            let mut is_max = true;
            'window: for dy in -r..=r {
                let ny = y as isize + dy;
                if ny < 0 || ny >= rows as isize {
                    continue;
                }
                for dx in -r..=r {
                    let nx = x as isize + dx;
                    if nx < 0 || nx >= cols as isize || (dx == 0 && dy == 0) {
                        continue;
                    }
                    let n = adjusted(nx as usize, ny as usize);
                    // Strictly greater wins; an equal neighbour wins when it comes first in raster order.
                    let earlier = dy < 0 || (dy == 0 && dx < 0);
                    if n > s || (n == s && earlier) {
                        is_max = false;
                        break 'window;
                    }
                }
            }
            if is_max {
                out.push(Candidate {
                    x: x as f32,
                    y: y as f32,
                    score: raw,
                });
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array2;

    fn brute_force(
        scores: &Array2<f32>,
        thr: f32,
        r: usize,
        region: ValidRegion,
    ) -> Vec<(usize, usize)> {
        let (rows, cols) = scores.dim();
        let mut out = vec![];
        for y in region.border..region.height - region.border {
            for x in region.border..region.width - region.border {
                let s = scores[[y, x]];
                if s <= thr {
                    continue;
                }
                let mut ok = true;
                for ny in y.saturating_sub(r)..(y + r + 1).min(rows) {
                    for nx in x.saturating_sub(r)..(x + r + 1).min(cols) {
                        let n = scores[[ny, nx]];
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
}
