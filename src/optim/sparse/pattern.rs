//! The block sparsity pattern of a symmetric positive-definite system,
//! built once per problem (a pose graph's normal equations, bundle
//! adjustment's reduced camera system).
//!
//! Free nodes (poses) become block columns of size `N`, placed in the
//! elimination order of [`super::ordering`]; each edge (a pair of nodes
//! coupled by a measurement, or by a shared point) adds one off-diagonal
//! block. `H` is stored as its lower triangle in
//! compressed sparse columns (what faer's supernodal Cholesky works on, so it
//! is factorised without a copy): block column `c` holds the lower triangle of
//! its diagonal block, then the full `N×N` blocks of the connected block rows
//! `r > c` (ascending). Every block is described by the start, in the value
//! array, of each of its `N` columns, so entry `(a, b)` of an off-diagonal
//! block lives at `column_starts[b] + a` (of a diagonal block, `a ≥ b`, at
//! `column_starts[b] + a − b`) and assembly is a scatter with no search.

use nalgebra::SMatrix;

use super::ordering::block_elimination_positions;
use crate::optim::error::OptimError;

/// Where one `N×N` block of `H` lives in the CSC value array.
pub(crate) type BlockSlot<const N: usize> = [usize; N];

/// Where one edge's contributions go.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct EdgeSlots {
    /// Block column of the `from` node, if it is free.
    pub from_block: Option<usize>,
    /// Block column of the `to` node, if it is free.
    pub to_block: Option<usize>,
    /// The off-diagonal block, if both are free: its index in
    /// `off_diagonal_slots` and whether `from` is its block row
    /// (`H_from,to`) rather than its block column (`H_to,from`).
    pub off_diagonal: Option<(usize, bool)>,
}

/// The CSC structure of the lower triangle of `H` and the block positions.
#[derive(Debug, Clone)]
pub(crate) struct BlockPattern<const N: usize> {
    /// Block (position in the elimination order) of each node, `None` for
    /// nodes held constant.
    pub block_of_node: Vec<Option<usize>>,
    /// Number of free nodes (block columns).
    pub block_count: usize,
    /// CSC column pointers (`N · block_count + 1`).
    pub column_pointers: Vec<usize>,
    /// CSC row indices, sorted within each column, diagonal first.
    pub row_indices: Vec<usize>,
    /// The diagonal block of each block column.
    pub diagonal_slots: Vec<BlockSlot<N>>,
    /// The distinct off-diagonal blocks.
    pub off_diagonal_slots: Vec<BlockSlot<N>>,
    /// Per edge, where its blocks go.
    pub edge_slots: Vec<EdgeSlots>,
    /// Index in the value array of each scalar diagonal entry `H_kk`.
    pub diagonal_value_indices: Vec<usize>,
}

impl<const N: usize> BlockPattern<N> {
    /// Builds the pattern for `edges` (pairs `(from, to)`) over nodes whose
    /// `held_constant` flag is false. Edges touching a held-constant node add
    /// no block; repeated edges share one block (each still gets its
    /// [`EdgeSlots`]).
    pub fn new(held_constant: &[bool], edges: &[(usize, usize)]) -> Result<Self, OptimError> {
        let mut natural_block = vec![None; held_constant.len()];
        let mut block_count = 0;
        for (node, &constant) in held_constant.iter().enumerate() {
            if !constant {
                natural_block[node] = Some(block_count);
                block_count += 1;
            }
        }
        let natural_pairs: Vec<(usize, usize)> = edges
            .iter()
            .filter_map(|&(from, to)| Some((natural_block[from]?, natural_block[to]?)))
            .collect();
        let positions = block_elimination_positions(block_count, &natural_pairs)?;
        let block_of_node: Vec<Option<usize>> = natural_block
            .iter()
            .map(|block| block.map(|natural| positions[natural]))
            .collect();

        // Block rows below the diagonal in each block column.
        let mut rows_of_column: Vec<Vec<usize>> = vec![Vec::new(); block_count];
        for &(a, b) in &natural_pairs {
            let (a, b) = (positions[a], positions[b]);
            rows_of_column[a.min(b)].push(a.max(b));
        }
        for rows in &mut rows_of_column {
            rows.sort_unstable();
            rows.dedup();
        }

        let dimension = N * block_count;
        let mut column_pointers = Vec::with_capacity(dimension + 1);
        let mut row_indices = Vec::new();
        let mut diagonal_slots = Vec::with_capacity(block_count);
        let mut diagonal_value_indices = Vec::with_capacity(dimension);
        let mut first_slot_of_column = Vec::with_capacity(block_count);
        let mut off_diagonal_slots = Vec::new();
        column_pointers.push(0);
        for (column, rows) in rows_of_column.iter().enumerate() {
            first_slot_of_column.push(off_diagonal_slots.len());
            let mut slots = vec![[0usize; N]; rows.len()];
            let mut diagonal = [0usize; N];
            for b in 0..N {
                diagonal[b] = row_indices.len();
                diagonal_value_indices.push(row_indices.len());
                row_indices.extend(column * N + b..column * N + N);
                for (position, &row) in rows.iter().enumerate() {
                    slots[position][b] = row_indices.len();
                    row_indices.extend(row * N..row * N + N);
                }
                column_pointers.push(row_indices.len());
            }
            diagonal_slots.push(diagonal);
            off_diagonal_slots.extend(slots);
        }

        let edge_slots = edges
            .iter()
            .map(|&(from, to)| {
                let from_block = block_of_node[from];
                let to_block = block_of_node[to];
                let off_diagonal = match (from_block, to_block) {
                    (Some(a), Some(b)) => {
                        let (column, row) = (a.min(b), a.max(b));
                        rows_of_column[column]
                            .binary_search(&row)
                            .ok()
                            .map(|position| (first_slot_of_column[column] + position, a > b))
                    }
                    _ => None,
                };
                EdgeSlots {
                    from_block,
                    to_block,
                    off_diagonal,
                }
            })
            .collect();

        Ok(Self {
            block_of_node,
            block_count,
            column_pointers,
            row_indices,
            diagonal_slots,
            off_diagonal_slots,
            edge_slots,
            diagonal_value_indices,
        })
    }

    /// Size of the linear system (`N` per free node).
    pub fn dimension(&self) -> usize {
        N * self.block_count
    }

    /// Number of stored values (lower triangle).
    pub fn value_count(&self) -> usize {
        self.row_indices.len()
    }
}

/// Adds a symmetric `N×N` block to a diagonal block of the lower-triangle
/// value array (only `block`'s lower triangle is read).
pub(crate) fn add_diagonal_block<const N: usize>(
    values: &mut [f64],
    slot: &BlockSlot<N>,
    block: &SMatrix<f64, N, N>,
) {
    // Lower triangle: column b holds rows b..N, starting at slot[b].
    for (b, &start) in slot.iter().enumerate() {
        let column = block.column(b);
        for (value, &entry) in values[start..start + N - b]
            .iter_mut()
            .zip(column.iter().skip(b))
        {
            *value += entry;
        }
    }
}

/// Adds a full `N×N` block to an off-diagonal block of the value array
/// (`block` is in the block's row/column orientation: rows of its block row).
pub(crate) fn add_full_block<const N: usize>(
    values: &mut [f64],
    slot: &BlockSlot<N>,
    block: &SMatrix<f64, N, N>,
) {
    for (b, &start) in slot.iter().enumerate() {
        for (value, &entry) in values[start..start + N]
            .iter_mut()
            .zip(block.column(b).iter())
        {
            *value += entry;
        }
    }
}
