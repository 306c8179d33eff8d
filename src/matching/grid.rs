//! ORB-SLAM3's keypoint grid (`Frame::AssignFeaturesToGrid` /
//! `GetFeaturesInArea`): 64 x 48 cells over the image for fast area queries.

use crate::features::Keypoint;

/// Cells across.
pub const GRID_COLS: usize = 64;
/// Cells down.
pub const GRID_ROWS: usize = 48;

#[derive(Clone, Copy, Debug, PartialEq)]
struct Entry {
    index: usize,
    x: f32,
    y: f32,
    octave: i32,
}

/// Keypoints bucketed into a 64 x 48 grid over `[0, width) x [0, height)`.
/// Keypoints outside the image are not indexed.
#[derive(Clone, Debug, PartialEq)]
pub struct KeypointGrid {
    width: f32,
    height: f32,
    inv_cell_w: f32,
    inv_cell_h: f32,
    /// CSR layout: cell c holds `entries[starts[c]..starts[c + 1]]`.
    starts: Vec<usize>,
    entries: Vec<Entry>,
}

impl KeypointGrid {
    /// Indexes the keypoints of an image of `width` x `height` pixels.
    pub fn new(keypoints: &[Keypoint], width: usize, height: usize) -> Self {
        let (w, h) = (width.max(1) as f32, height.max(1) as f32);
        let inv_cell_w = GRID_COLS as f32 / w;
        let inv_cell_h = GRID_ROWS as f32 / h;
        let cell_of = |kp: &Keypoint| -> Option<usize> {
            let cx = (kp.x * inv_cell_w).round();
            let cy = (kp.y * inv_cell_h).round();
            // ORB-SLAM3's PosInGrid rounds and rejects cells outside the grid.
            if !(kp.x >= 0.0 && kp.y >= 0.0 && kp.x < w && kp.y < h) {
                return None;
            }
            let cx = (cx as usize).min(GRID_COLS - 1);
            let cy = (cy as usize).min(GRID_ROWS - 1);
            Some(cy * GRID_COLS + cx)
        };
        let mut counts = vec![0usize; GRID_COLS * GRID_ROWS + 1];
        for kp in keypoints {
            if let Some(c) = cell_of(kp) {
                counts[c + 1] += 1;
            }
        }
        for c in 1..counts.len() {
            counts[c] += counts[c - 1];
        }
        let starts = counts.clone();
        let mut fill = counts;
        let mut entries = vec![
            Entry {
                index: 0,
                x: 0.0,
                y: 0.0,
                octave: 0
            };
            starts[GRID_COLS * GRID_ROWS]
        ];
        for (index, kp) in keypoints.iter().enumerate() {
            if let Some(c) = cell_of(kp) {
                entries[fill[c]] = Entry {
                    index,
                    x: kp.x,
                    y: kp.y,
                    octave: kp.octave,
                };
                fill[c] += 1;
            }
        }
        Self {
            width: w,
            height: h,
            inv_cell_w,
            inv_cell_h,
            starts,
            entries,
        }
    }

    /// Indices of the keypoints with |x - kp.x| < r and |y - kp.y| < r (a
    /// square, as ORB-SLAM3), and, when `octaves` is given, an octave in that
    /// inclusive range. Sorted by index.
    pub fn features_in_area(
        &self,
        x: f32,
        y: f32,
        r: f32,
        octaves: Option<(i32, i32)>,
    ) -> Vec<usize> {
        let mut out = Vec::new();
        if !(r.is_finite() && r >= 0.0 && x.is_finite() && y.is_finite()) {
            return out;
        }
        let span = |lo: f32, hi: f32, inv: f32, n: usize, extent: f32| -> Option<(usize, usize)> {
            if hi < 0.0 || lo >= extent {
                return None;
            }
            let first = ((lo * inv).floor() - 1.0).max(0.0) as usize;
            let last = (((hi * inv).ceil() + 1.0).max(0.0) as usize).min(n - 1);
            (first <= last).then_some((first, last))
        };
        let Some((cx0, cx1)) = span(x - r, x + r, self.inv_cell_w, GRID_COLS, self.width) else {
            return out;
        };
        let Some((cy0, cy1)) = span(y - r, y + r, self.inv_cell_h, GRID_ROWS, self.height) else {
            return out;
        };
        for cy in cy0..=cy1 {
            for cx in cx0..=cx1 {
                let c = cy * GRID_COLS + cx;
                for e in &self.entries[self.starts[c]..self.starts[c + 1]] {
                    if let Some((lo, hi)) = octaves {
                        if e.octave < lo || e.octave > hi {
                            continue;
                        }
                    }
                    if (e.x - x).abs() < r && (e.y - y).abs() < r {
                        out.push(e.index);
                    }
                }
            }
        }
        out.sort_unstable();
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kp(x: f32, y: f32, octave: i32) -> Keypoint {
        Keypoint {
            x,
            y,
            size: 31.0,
            angle: 0.0,
            response: 1.0,
            octave,
        }
    }

    #[test]
    fn area_query_equals_a_linear_scan() {
        let kps: Vec<Keypoint> = (0..500)
            .map(|i| {
                let t = i as f32;
                kp((t * 37.3) % 640.0, (t * 17.9) % 480.0, i % 4)
            })
            .collect();
        let grid = KeypointGrid::new(&kps, 640, 480);
        for &(x, y, r, oct) in &[
            (100.0, 100.0, 30.0, None),
            (0.0, 0.0, 50.0, Some((1, 2))),
            (639.0, 479.0, 12.5, None),
            (320.0, 240.0, 400.0, Some((0, 0))),
            (-20.0, 10.0, 25.0, None),
        ] {
            let got = grid.features_in_area(x, y, r, oct);
            let want: Vec<usize> = kps
                .iter()
                .enumerate()
                .filter(|(_, k)| (k.x - x).abs() < r && (k.y - y).abs() < r)
                .filter(|(_, k)| oct.is_none_or(|(lo, hi)| k.octave >= lo && k.octave <= hi))
                .map(|(i, _)| i)
                .collect();
            assert_eq!(got, want, "query ({x}, {y}, {r}, {oct:?})");
        }
    }
}
