//! The Schur complement's per-observation blocks, shared by the dense and
//! the sparse reduced-system passes.

use nalgebra::{Matrix6, Matrix6x3};

/// One Y = W·V⁻¹ of the Schur complement, with its free pose.
#[derive(Debug, Clone, Copy)]
pub(super) struct ScaledBlock {
    /// Index of the free pose.
    pub free_pose: usize,
    /// Index of the observation within the chunk.
    pub local_observation: usize,
    /// Rank among the point's observations from free poses (inactive ones
    /// included): its index in the sparse path's per-point pair table.
    pub rank: usize,
    /// `W V⁻¹` (6×3).
    pub block: Matrix6x3<f64>,
}

/// `Y Wᵀ` (6×3 · 3×6), written out so it is inlined into the Schur passes
/// of both paths (nalgebra's generic product was not inlined into the
/// sparse pass and took a fifth of its iteration time) and both form
/// bitwise the same blocks.
#[inline(always)]
pub(super) fn outer_product(y: &Matrix6x3<f64>, w: &Matrix6x3<f64>) -> Matrix6<f64> {
    let mut out = Matrix6::zeros();
    for c in 0..6 {
        let (w0, w1, w2) = (w[(c, 0)], w[(c, 1)], w[(c, 2)]);
        for r in 0..6 {
            out[(r, c)] = y[(r, 0)] * w0 + y[(r, 1)] * w1 + y[(r, 2)] * w2;
        }
    }
    out
}
