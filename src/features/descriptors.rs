//! Bilinear sampling of the coarse descriptor map at keypoint positions.

use ndarray::ArrayView3;

use super::model::CELL;

/// Samples the descriptor map `desc` [D, Hc, Wc] at each (x, y) pixel position
/// and appends one unit-L2 row of D floats per point to `out`.
///
/// Cell (i, j) of the map is centred on pixel (8j + 3.5, 8i + 3.5), as in
/// SuperPoint's `grid_sample(align_corners=False)`; positions beyond the outer
/// cell centres are clamped to them. `scratch` is reused between calls.
pub fn sample_descriptors(
    desc: ArrayView3<'_, f32>,
    points: &[(f32, f32)],
    out: &mut Vec<f32>,
    scratch: &mut Vec<f32>,
) {
    let (d, hc, wc) = desc.dim();
    let n = points.len();
    if n == 0 || d == 0 || hc == 0 || wc == 0 {
        return;
    }
    // Per point: the four corner offsets within a channel plane and their weights.
    let centre = (CELL as f32 - 1.0) / 2.0;
    let taps: Vec<([usize; 4], [f32; 4])> = points
        .iter()
        .map(|&(x, y)| {
            let u = ((x - centre) / CELL as f32).clamp(0.0, (wc - 1) as f32);
            let v = ((y - centre) / CELL as f32).clamp(0.0, (hc - 1) as f32);
            let (u0, v0) = (u.floor() as usize, v.floor() as usize);
            let (u1, v1) = ((u0 + 1).min(wc - 1), (v0 + 1).min(hc - 1));
            let (fu, fv) = (u - u0 as f32, v - v0 as f32);
            (
                [v0 * wc + u0, v0 * wc + u1, v1 * wc + u0, v1 * wc + u1],
                [
                    (1.0 - fu) * (1.0 - fv),
                    fu * (1.0 - fv),
                    (1.0 - fu) * fv,
                    fu * fv,
                ],
            )
        })
        .collect();
    // Channel-major accumulation keeps each channel plane hot in cache.
    scratch.clear();
    scratch.resize(d * n, 0.0);
    for (c, plane_out) in scratch.chunks_exact_mut(n).enumerate() {
        let plane = desc.index_axis(ndarray::Axis(0), c);
        match plane.as_slice() {
            Some(p) => {
                for (o, (idx, w)) in plane_out.iter_mut().zip(&taps) {
                    *o = w[0] * p[idx[0]] + w[1] * p[idx[1]] + w[2] * p[idx[2]] + w[3] * p[idx[3]];
                }
            }
            None => {
                for (o, (idx, w)) in plane_out.iter_mut().zip(&taps) {
                    let at = |i: usize| plane[[i / wc, i % wc]];
                    *o = w[0] * at(idx[0])
                        + w[1] * at(idx[1])
                        + w[2] * at(idx[2])
                        + w[3] * at(idx[3]);
                }
            }
        }
    }
    let start = out.len();
    out.resize(start + n * d, 0.0);
    let rows = &mut out[start..];
    // The channel-major scratch into keypoint rows, in tiles of
    // TILE x TILE so that both sides stay in cache (a row-by-row gather
    // reads the scratch with a stride of n floats).
    for k0 in (0..n).step_by(TILE) {
        let k1 = (k0 + TILE).min(n);
        for c0 in (0..d).step_by(TILE) {
            let c1 = (c0 + TILE).min(d);
            for k in k0..k1 {
                let row = &mut rows[k * d + c0..k * d + c1];
                for (value, c) in row.iter_mut().zip(c0..c1) {
                    *value = scratch[c * n + k];
                }
            }
        }
    }
    for row in rows.chunks_exact_mut(d) {
        let norm_sq = row.iter().fold(0.0f32, |acc, v| acc + v * v);
        let inv = 1.0 / norm_sq.sqrt().max(1e-12);
        row.iter_mut().for_each(|v| *v *= inv);
    }
}

/// The tile side of [`sample_descriptors`]' transpose (16 floats: one
/// 64-byte cache line).
const TILE: usize = 16;

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array3;

    #[test]
    fn cell_centres_return_the_cell_descriptor_and_midpoints_blend() {
        let mut desc = Array3::<f32>::zeros((2, 2, 3));
        desc[[0, 0, 0]] = 1.0; // cell (0,0) = (1, 0)
        desc[[1, 0, 1]] = 1.0; // cell (0,1) = (0, 1)
        let mut out = vec![];
        let mut scratch = vec![];
        sample_descriptors(
            desc.view(),
            &[(3.5, 3.5), (11.5, 3.5), (7.5, 3.5)],
            &mut out,
            &mut scratch,
        );
        assert_eq!(&out[0..2], &[1.0, 0.0]);
        assert_eq!(&out[2..4], &[0.0, 1.0]);
        let h = std::f32::consts::FRAC_1_SQRT_2;
        assert!((out[4] - h).abs() < 1e-6 && (out[5] - h).abs() < 1e-6);
    }

    #[test]
    fn rows_are_unit_norm_and_positions_clamp() {
        let desc = Array3::from_shape_fn((16, 4, 5), |(c, i, j)| {
            (c + 2 * i + 3 * j) as f32 * 0.1 - 0.7
        });
        let pts = [(0.0, 0.0), (39.0, 31.0), (17.2, 9.9), (-5.0, 100.0)];
        let (mut out, mut scratch) = (vec![], vec![]);
        sample_descriptors(desc.view(), &pts, &mut out, &mut scratch);
        assert_eq!(out.len(), 4 * 16);
        for row in out.chunks(16) {
            let n: f32 = row.iter().map(|v| v * v).sum();
            assert!((n - 1.0).abs() < 1e-5);
        }
    }
    /// Bilinear sampling and normalisation written plainly, one keypoint
    /// and one channel at a time, with the same arithmetic per value.
    fn sample_plainly(desc: &Array3<f32>, points: &[(f32, f32)]) -> Vec<f32> {
        let (d, hc, wc) = desc.dim();
        let centre = (CELL as f32 - 1.0) / 2.0;
        let mut out = vec![];
        for &(x, y) in points {
            let u = ((x - centre) / CELL as f32).clamp(0.0, (wc - 1) as f32);
            let v = ((y - centre) / CELL as f32).clamp(0.0, (hc - 1) as f32);
            let (u0, v0) = (u.floor() as usize, v.floor() as usize);
            let (u1, v1) = ((u0 + 1).min(wc - 1), (v0 + 1).min(hc - 1));
            let (fu, fv) = (u - u0 as f32, v - v0 as f32);
            let w = [
                (1.0 - fu) * (1.0 - fv),
                fu * (1.0 - fv),
                (1.0 - fu) * fv,
                fu * fv,
            ];
            let row: Vec<f32> = (0..d)
                .map(|c| {
                    w[0] * desc[[c, v0, u0]]
                        + w[1] * desc[[c, v0, u1]]
                        + w[2] * desc[[c, v1, u0]]
                        + w[3] * desc[[c, v1, u1]]
                })
                .collect();
            let norm_sq = row.iter().fold(0.0f32, |acc, v| acc + v * v);
            let inv = 1.0 / norm_sq.sqrt().max(1e-12);
            out.extend(row.iter().map(|v| v * inv));
        }
        out
    }

    #[test]
    fn the_tiled_transpose_gives_the_plain_result_bit_for_bit() {
        // Sizes that are not multiples of the tile, on both axes.
        let desc = Array3::from_shape_fn((37, 6, 9), |(c, i, j)| {
            ((c * 31 + i * 7 + j * 13) % 17) as f32 * 0.173 - 1.3
        });
        let points: Vec<(f32, f32)> = (0..41)
            .map(|k| ((k * 37 % 80) as f32 * 0.93, (k * 11 % 52) as f32 * 1.07))
            .collect();
        let (mut out, mut scratch) = (vec![0.5; 3], vec![]);
        sample_descriptors(desc.view(), &points, &mut out, &mut scratch);
        let want = sample_plainly(&desc, &points);
        assert_eq!(&out[..3], &[0.5; 3], "appends after what is there");
        assert_eq!(out.len(), 3 + want.len());
        for (i, (got, want)) in out[3..].iter().zip(&want).enumerate() {
            assert_eq!(got.to_bits(), want.to_bits(), "value {i}");
        }
    }
}
