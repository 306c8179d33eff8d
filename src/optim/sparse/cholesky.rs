//! faer's sparse Cholesky (LLᵀ) with the symbolic analysis done once.
//!
//! The matrix arrives as its lower triangle, already in elimination order
//! (see [`super::ordering`]), so faer is told to use it as is. The elimination
//! structure depends only on the sparsity pattern, which a pose graph (or a
//! bundle adjustment's reduced camera system) keeps between iterations; each
//! iteration (each damping tried) only refactorises numerically and solves.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::LltError;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};

use crate::optim::error::OptimError;

/// The CSC structure of the transpose (rows come out sorted).
fn transpose_pattern(
    dimension: usize,
    column_pointers: &[usize],
    row_indices: &[usize],
) -> (Vec<usize>, Vec<usize>) {
    let mut counts = vec![0usize; dimension + 1];
    for &row in row_indices {
        counts[row + 1] += 1;
    }
    for index in 0..dimension {
        counts[index + 1] += counts[index];
    }
    let transposed_pointers = counts.clone();
    let mut next = counts;
    let mut transposed_rows = vec![0usize; row_indices.len()];
    for column in 0..dimension {
        for &row in &row_indices[column_pointers[column]..column_pointers[column + 1]] {
            transposed_rows[next[row]] = column;
            next[row] += 1;
        }
    }
    (transposed_pointers, transposed_rows)
}

/// A reusable sparse LLᵀ factorisation for one fixed lower-triangular pattern.
pub(crate) struct SparseCholesky {
    dimension: usize,
    column_pointers: Vec<usize>,
    row_indices: Vec<usize>,
    symbolic: SymbolicCholesky<usize>,
    factor_values: Vec<f64>,
    workspace: MemBuffer,
}

impl std::fmt::Debug for SparseCholesky {
    fn fmt(&self, formatter: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        formatter
            .debug_struct("SparseCholesky")
            .field("dimension", &self.dimension)
            .field("stored_values", &self.row_indices.len())
            .field("factor_values", &self.factor_values.len())
            .finish_non_exhaustive()
    }
}

impl SparseCholesky {
    /// The symbolic analysis of the lower triangle given in CSC form.
    pub fn analyse(
        dimension: usize,
        column_pointers: &[usize],
        row_indices: &[usize],
    ) -> Result<Self, OptimError> {
        // With the identity ordering faer's symbolic analysis reads its input
        // as the upper triangle whatever the side, so it gets the transpose.
        let (upper_column_pointers, upper_row_indices) =
            transpose_pattern(dimension, column_pointers, row_indices);
        let upper_pattern = SymbolicSparseColMatRef::new_checked(
            dimension,
            dimension,
            &upper_column_pointers,
            None,
            &upper_row_indices,
        );
        let symbolic = factorize_symbolic_cholesky(
            upper_pattern,
            Side::Upper,
            SymmetricOrdering::Identity,
            CholeskySymbolicParams::default(),
        )
        .map_err(|error| OptimError::SymbolicFactorisation {
            reason: format!("{error:?}"),
        })?;
        let requirement = StackReq::any_of(&[
            symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
            symbolic.solve_in_place_scratch::<f64>(1, Par::Seq),
        ]);
        let workspace =
            MemBuffer::try_new(requirement).map_err(|_| OptimError::SymbolicFactorisation {
                reason: "out of memory for the factorisation workspace".to_owned(),
            })?;
        Ok(Self {
            dimension,
            column_pointers: column_pointers.to_vec(),
            row_indices: row_indices.to_vec(),
            factor_values: vec![0.0; symbolic.len_val()],
            symbolic,
            workspace,
        })
    }

    /// Factorises `H` (lower-triangle values in the analysed pattern) and
    /// overwrites `right_hand_side` with `H⁻¹ · right_hand_side`.
    ///
    /// Fails with the pivot index if `H` is not numerically positive definite.
    pub fn factorise_and_solve(
        &mut self,
        values: &[f64],
        right_hand_side: &mut [f64],
    ) -> Result<(), usize> {
        let pattern = SymbolicSparseColMatRef::new_checked(
            self.dimension,
            self.dimension,
            &self.column_pointers,
            None,
            &self.row_indices,
        );
        let matrix = SparseColMatRef::new(pattern, values);
        let factor = self
            .symbolic
            .factorize_numeric_llt(
                &mut self.factor_values,
                matrix,
                Side::Lower,
                Default::default(),
                Par::Seq,
                MemStack::new(&mut self.workspace),
                Default::default(),
            )
            .map_err(|error| match error {
                LltError::NonPositivePivot { index } => index,
            })?;
        let dimension = self.dimension;
        let rhs = MatMut::from_column_major_slice_mut(right_hand_side, dimension, 1);
        factor.solve_in_place_with_conj(
            Conj::No,
            rhs,
            Par::Seq,
            MemStack::new(&mut self.workspace),
        );
        Ok(())
    }
}
