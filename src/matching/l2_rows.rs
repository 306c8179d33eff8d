//! All L2 distances between two blocks of float descriptors, a row of the
//! distance matrix at a time, through a matrix product:
//! `|q - t|² = |q|² + |t|² - 2 q·t`. A query of 1000 SuperPoint rows against
//! a loop candidate's 5000 map points is 1.3 G multiply-adds: faer's GEMM
//! (run-time SIMD dispatch) does them several times faster than one
//! distance at a time (`BENCHMARKS.md`, "Loop verification per candidate").
//!
//! The distances agree with [`DescriptorDistance::distance_to`] up to
//! rounding (exactly for small exactly-representable values, which the
//! matcher's property tests use).
//!
//! [`DescriptorDistance::distance_to`]: crate::features::descriptor_set::DescriptorDistance::distance_to

use faer::linalg::matmul::matmul;
use faer::{Accum, MatMut, MatRef, Par};

/// Query rows per matrix product: 64 rows against 5000 train rows is a
/// 1.3 MB block of distances.
const BLOCK_ROWS: usize = 64;

/// Calls `row(i, distances)` for every query row `i` in ascending order,
/// with the L2 distances from row `i` to every train row. `query` and
/// `train` hold rows of `dim` floats (`dim > 0`).
pub(super) fn for_each_l2_row(
    query: &[f32],
    train: &[f32],
    dim: usize,
    row: &mut dyn FnMut(usize, &[f32]),
) {
    let (n_query, n_train) = (query.len() / dim, train.len() / dim);
    if n_train == 0 {
        (0..n_query).for_each(|i| row(i, &[]));
        return;
    }
    let train_norms: Vec<f32> = train.chunks_exact(dim).map(squared_norm).collect();
    let rhs = MatRef::from_row_major_slice(&train[..n_train * dim], n_train, dim).transpose();
    let mut block = vec![0.0f32; BLOCK_ROWS.min(n_query) * n_train];
    for start in (0..n_query).step_by(BLOCK_ROWS) {
        let rows = BLOCK_ROWS.min(n_query - start);
        let lhs =
            MatRef::from_row_major_slice(&query[start * dim..(start + rows) * dim], rows, dim);
        let dots = MatMut::from_row_major_slice_mut(&mut block[..rows * n_train], rows, n_train);
        matmul(dots, Accum::Replace, lhs, rhs, 1.0f32, Par::Seq);
        for r in 0..rows {
            let i = start + r;
            let query_norm = squared_norm(&query[i * dim..(i + 1) * dim]);
            let distances = &mut block[r * n_train..(r + 1) * n_train];
            for (d, train_norm) in distances.iter_mut().zip(&train_norms) {
                let squared = query_norm + train_norm - 2.0 * *d;
                // Rounding can take a true 0 below 0; NaN stays NaN.
                *d = if squared < 0.0 { 0.0 } else { squared.sqrt() };
            }
            row(i, distances);
        }
    }
}

/// `|v|²`, with eight partial sums so that the loop vectorises.
fn squared_norm(v: &[f32]) -> f32 {
    let mut acc = [0.0f32; 8];
    let chunks = v.chunks_exact(8);
    let tail: f32 = chunks.remainder().iter().map(|x| x * x).sum();
    for c in chunks {
        for k in 0..8 {
            acc[k] += c[k] * c[k];
        }
    }
    acc.iter().sum::<f32>() + tail
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::features::descriptor_set::DescriptorDistance;

    /// Unit rows like SuperPoint's, from a fixed generator.
    fn unit_rows(n: usize, dim: usize, seed: u64) -> Vec<f32> {
        let mut state = seed;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 40) as f32 / (1u64 << 24) as f32) - 0.5
        };
        let mut rows: Vec<f32> = (0..n * dim).map(|_| next()).collect();
        for r in rows.chunks_exact_mut(dim) {
            let norm = squared_norm(r).sqrt();
            r.iter_mut().for_each(|x| *x /= norm);
        }
        rows
    }

    #[test]
    fn distances_match_one_at_a_time_within_rounding() {
        let dim = 256;
        // More query rows than a block, and a partial last block.
        let (q, t) = (unit_rows(150, dim, 1), unit_rows(70, dim, 2));
        let mut seen = 0;
        for_each_l2_row(&q, &t, dim, &mut |i, row| {
            assert_eq!(i, seen);
            seen += 1;
            assert_eq!(row.len(), 70);
            for (j, d) in row.iter().enumerate() {
                let direct = q[i * dim..(i + 1) * dim].distance_to(&t[j * dim..(j + 1) * dim]);
                assert!(
                    (d - direct).abs() < 1e-5,
                    "row {i}, column {j}: {d} vs {direct}"
                );
            }
        });
        assert_eq!(seen, 150);
    }

    #[test]
    fn identical_rows_are_at_zero_and_an_empty_train_gives_empty_rows() {
        let q = unit_rows(3, 16, 3);
        for_each_l2_row(&q, &q, 16, &mut |i, row| {
            assert!(row[i] >= 0.0 && row[i] < 1e-3, "{}", row[i]);
        });
        let mut rows = 0;
        for_each_l2_row(&q, &[], 16, &mut |_, row| {
            assert!(row.is_empty());
            rows += 1;
        });
        assert_eq!(rows, 3);
    }
}
