//! faer's sparse Cholesky (LLᵀ) with the symbolic analysis done once.
//!
//! The fill-reducing ordering (AMD) and the elimination structure depend
//! only on the sparsity pattern, which a pose graph keeps between
//! iterations; each iteration only refactorises numerically and solves.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::LltError;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};

use crate::optim::error::OptimError;

/// A reusable sparse LLᵀ factorisation for one fixed upper-triangular pattern.
pub(super) struct SparseCholesky {
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
    /// The symbolic analysis of the upper triangle given in CSC form.
    pub fn analyse(
        dimension: usize,
        column_pointers: &[usize],
        row_indices: &[usize],
    ) -> Result<Self, OptimError> {
        let pattern = SymbolicSparseColMatRef::new_checked(
            dimension,
            dimension,
            column_pointers,
            None,
            row_indices,
        );
        let symbolic = factorize_symbolic_cholesky(
            pattern,
            Side::Upper,
            SymmetricOrdering::Amd,
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

    /// Factorises `H` (upper-triangle values in the analysed pattern) and
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
                Side::Upper,
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
