//! The fill-reducing ordering of the free nodes: AMD on the block graph.
//!
//! Ordering the `N×N` blocks instead of the scalars gives the same ordering
//! quality (AMD merges a block's identical scalar columns anyway) on a graph
//! `N²` times smaller, and lets the normal equations be assembled directly
//! in factorisation order, so faer never permutes `H`.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::amd;
use faer::sparse::SymbolicSparseColMatRef;

use crate::optim::error::OptimError;

/// For each block (free node in natural order), its position in the
/// elimination order. `neighbours` are block pairs `(a, b)`, `a ≠ b`.
pub(crate) fn block_elimination_positions(
    block_count: usize,
    neighbours: &[(usize, usize)],
) -> Result<Vec<usize>, OptimError> {
    // Upper-triangle block CSC with the diagonal, as AMD expects.
    let mut rows_of_column: Vec<Vec<usize>> = vec![Vec::new(); block_count];
    for &(a, b) in neighbours {
        rows_of_column[a.max(b)].push(a.min(b));
    }
    let mut column_pointers = Vec::with_capacity(block_count + 1);
    let mut row_indices = Vec::new();
    column_pointers.push(0);
    for (column, rows) in rows_of_column.iter_mut().enumerate() {
        rows.sort_unstable();
        rows.dedup();
        row_indices.extend_from_slice(rows);
        row_indices.push(column);
        column_pointers.push(row_indices.len());
    }
    let pattern = SymbolicSparseColMatRef::new_checked(
        block_count,
        block_count,
        &column_pointers,
        None,
        &row_indices,
    );
    let failure = |reason: String| OptimError::SymbolicFactorisation { reason };
    let mut workspace =
        MemBuffer::try_new(amd::order_scratch::<usize>(block_count, row_indices.len()))
            .map_err(|_| failure("out of memory for the AMD workspace".to_owned()))?;
    let mut order = vec![0usize; block_count];
    let mut positions = vec![0usize; block_count];
    amd::order(
        &mut order,
        &mut positions,
        pattern,
        amd::Control::default(),
        MemStack::new(&mut workspace),
    )
    .map_err(|error| failure(format!("{error:?}")))?;
    Ok(positions)
}
