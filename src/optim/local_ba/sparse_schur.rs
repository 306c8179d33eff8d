//! The block-sparse reduced camera system (the sparse path).
//!
//! Eliminating a point couples every pair of free poses that observe it, so
//! the block pattern of `S = H_cc + μD − Σ W V⁻¹ Wᵀ` is the diagonal plus the
//! free pose pairs that share at least one point. [`ReducedPattern::new`]
//! collects those pairs once per bundle adjustment (from every observation,
//! so the pattern also holds after outliers are deactivated: a pair whose
//! shared points all became outliers keeps explicit zeros) and lays them out
//! with the shared [`BlockPattern<6>`] (AMD order, lower-triangle CSC). Per
//! free pose `a` it keeps the sorted list of its neighbours `b > a` with the
//! position of block `S_ab`; from those it tabulates, once, for every point
//! and every pair of its free observations, which block the pair's
//! `W V⁻¹ Wᵀ` goes to. A chunk's Schur pass then finds a pair's block by one
//! indexed load (a binary search per pair made the sparse Schur pass twice
//! as slow as the dense one).
//!
//! [`SparseReducedSolver`] holds faer's symbolic analysis of that pattern
//! (computed once) and, for each damping tried, sums the chunks' value
//! arrays, adds `H_cc + μD` on the diagonal blocks, permutes the right-hand
//! side into the elimination order, refactorises numerically and solves.

use nalgebra::{DVector, Matrix6, Matrix6x3, Vector6};

use super::blocks::{outer_product, ScaledBlock};
use super::layout::{Layout, FIXED_POSE};
use crate::optim::damping::marquardt_scale;
use crate::optim::sparse::{add_diagonal_block, BlockPattern, BlockSlot, SparseCholesky};
use crate::optim::OptimError;

/// Where block `S_ab` (`a < b`, free-pose indices) lives.
#[derive(Debug, Clone, Copy)]
pub(super) struct PairBlock {
    /// The column starts of the stored block.
    pub slot: BlockSlot<6>,
    /// True when `a` is the block row of the stored block (it holds `S_ab`),
    /// false when it holds `S_ba = S_abᵀ`.
    pub a_is_row: bool,
}

/// Entry of the per-point pair table for two observations from one pose.
const SAME_POSE: u32 = u32::MAX;

/// Index of the pair `(i, j)`, `i < j < m`, in a point's upper-triangle pair
/// list (row-major: `(0,1), (0,2), …, (1,2), …`).
#[inline]
fn pair_index(i: usize, j: usize, m: usize) -> usize {
    i * (2 * m - i - 1) / 2 + (j - i - 1)
}

/// The pattern of the reduced camera system and the pose-pair lookup.
#[derive(Debug)]
pub(super) struct ReducedPattern {
    /// The lower-triangle CSC layout over the free poses (as its nodes).
    pub pattern: BlockPattern<6>,
    /// Free pose `a`'s neighbours `b > a` are
    /// `neighbour_offsets[a]..neighbour_offsets[a + 1]`.
    neighbour_offsets: Vec<usize>,
    /// The neighbours, ascending within each free pose.
    neighbours: Vec<u32>,
    /// The block of each neighbour pair.
    neighbour_blocks: Vec<PairBlock>,
    /// Point `p`'s pairs of free observations (ranked in sorted-observation
    /// order, inactive ones included) are
    /// `point_pair_offsets[p]..point_pair_offsets[p + 1]` in `point_pairs`.
    point_pair_offsets: Vec<usize>,
    /// Per pair: index into `neighbour_blocks`, or [`SAME_POSE`].
    point_pairs: Vec<u32>,
}

impl ReducedPattern {
    /// Collects the free pose pairs sharing a point and builds the pattern.
    pub fn new(layout: &Layout) -> Result<Self, OptimError> {
        let free = layout.free_poses.len();
        let mut neighbours_of: Vec<Vec<u32>> = vec![Vec::new(); free];
        let mut point_poses: Vec<u32> = Vec::with_capacity(layout.max_observations_per_point);
        for point in 0..layout.point_offsets.len().saturating_sub(1) {
            point_poses.clear();
            point_poses.extend(
                layout.observations[layout.point_observations(point)]
                    .iter()
                    .map(|o| o.free_pose)
                    .filter(|&f| f != FIXED_POSE),
            );
            point_poses.sort_unstable();
            point_poses.dedup();
            for (i, &a) in point_poses.iter().enumerate() {
                neighbours_of[a as usize].extend_from_slice(&point_poses[i + 1..]);
            }
        }
        let mut neighbour_offsets = Vec::with_capacity(free + 1);
        let mut neighbours = Vec::new();
        neighbour_offsets.push(0);
        for list in &mut neighbours_of {
            list.sort_unstable();
            list.dedup();
            neighbours.extend_from_slice(list);
            neighbour_offsets.push(neighbours.len());
            *list = Vec::new();
        }
        let mut pairs = Vec::with_capacity(neighbours.len());
        for a in 0..free {
            for &b in &neighbours[neighbour_offsets[a]..neighbour_offsets[a + 1]] {
                pairs.push((a, b as usize));
            }
        }
        let pattern = BlockPattern::<6>::new(&vec![false; free], &pairs)?;
        let neighbour_blocks = pattern
            .edge_slots
            .iter()
            .map(|slots| {
                let (index, a_is_row) =
                    slots
                        .off_diagonal
                        .ok_or_else(|| OptimError::SymbolicFactorisation {
                            reason: "a covisible pose pair has no block in the pattern".to_owned(),
                        })?;
                Ok(PairBlock {
                    slot: pattern.off_diagonal_slots[index],
                    a_is_row,
                })
            })
            .collect::<Result<Vec<_>, OptimError>>()?;
        let mut reduced = Self {
            pattern,
            neighbour_offsets,
            neighbours,
            neighbour_blocks,
            point_pair_offsets: Vec::with_capacity(layout.point_offsets.len()),
            point_pairs: Vec::new(),
        };
        reduced.tabulate_point_pairs(layout)?;
        Ok(reduced)
    }

    /// Fills the per-point pair table.
    fn tabulate_point_pairs(&mut self, layout: &Layout) -> Result<(), OptimError> {
        let missing = || OptimError::SymbolicFactorisation {
            reason: "a covisible pose pair has no block in the pattern".to_owned(),
        };
        let mut point_poses: Vec<usize> = Vec::with_capacity(layout.max_observations_per_point);
        self.point_pair_offsets.push(0);
        for point in 0..layout.point_offsets.len().saturating_sub(1) {
            point_poses.clear();
            point_poses.extend(
                layout.observations[layout.point_observations(point)]
                    .iter()
                    .filter(|o| o.free_pose != FIXED_POSE)
                    .map(|o| o.free_pose as usize),
            );
            for (i, &a) in point_poses.iter().enumerate() {
                for &b in &point_poses[i + 1..] {
                    let entry = if a == b {
                        SAME_POSE
                    } else {
                        let index = self
                            .pair_block_index(a.min(b), a.max(b))
                            .ok_or_else(missing)?;
                        u32::try_from(index).map_err(|_| missing())?
                    };
                    self.point_pairs.push(entry);
                }
            }
            self.point_pair_offsets.push(self.point_pairs.len());
        }
        Ok(())
    }

    /// Index in `neighbour_blocks` of block `S_ab` of free poses `a < b`,
    /// `None` if they share no point.
    fn pair_block_index(&self, a: usize, b: usize) -> Option<usize> {
        let range = self.neighbour_offsets[a]..self.neighbour_offsets[a + 1];
        let position = self.neighbours[range.clone()]
            .binary_search(&u32::try_from(b).ok()?)
            .ok()?;
        Some(range.start + position)
    }

    /// The diagonal block of free pose `a`.
    #[inline]
    pub fn diagonal_block(&self, a: usize) -> Option<&BlockSlot<6>> {
        let position = self.pattern.block_of_node.get(a).copied().flatten()?;
        self.pattern.diagonal_slots.get(position)
    }

    /// Number of stored values (lower triangle).
    pub fn value_count(&self) -> usize {
        self.pattern.value_count()
    }

    /// The pair table of `point` (see `point_pairs`).
    #[inline]
    pub fn point_pairs(&self, point: usize) -> &[u32] {
        match (
            self.point_pair_offsets.get(point),
            self.point_pair_offsets.get(point + 1),
        ) {
            (Some(&start), Some(&end)) => self.point_pairs.get(start..end).unwrap_or(&[]),
            _ => &[],
        }
    }

    /// Subtracts one point's `W V⁻¹ Wᵀ` from the sparse values: `scaled`
    /// holds its active free observations' `Y = W V⁻¹` (ascending rank),
    /// `free_observations` the number of its free observations (the rank
    /// range). False when the table and the observations disagree (never
    /// expected: the table is built from the same layout).
    pub fn subtract_point(
        &self,
        values: &mut [f64],
        point: usize,
        free_observations: usize,
        scaled: &[ScaledBlock],
        pose_point: &[Matrix6x3<f64>],
    ) -> bool {
        let pairs = self.point_pairs(point);
        let m = free_observations;
        if pairs.len() != m * m.saturating_sub(1) / 2 {
            return false;
        }
        let mut complete = true;
        for (i, yi) in scaled.iter().enumerate() {
            // The products are formed and read as on the dense path (the
            // upper triangle of `Y_i W_iᵀ` on the diagonal), so the Schur
            // parts of both paths are bitwise the same.
            let wi = &pose_point[yi.local_observation];
            let own = outer_product(&yi.block, wi);
            complete &= self.subtract_diagonal_upper(values, yi.free_pose, &own);
            for yj in &scaled[i + 1..] {
                let wj = &pose_point[yj.local_observation];
                let product = outer_product(&yi.block, wj);
                let Some(&entry) = pairs.get(pair_index(yi.rank, yj.rank, m)) else {
                    complete = false;
                    continue;
                };
                if entry == SAME_POSE {
                    // Two observations of one point from one pose.
                    let block = product + product.transpose();
                    complete &= self.subtract_diagonal_upper(values, yi.free_pose, &block);
                    continue;
                }
                let Some(pair) = self.neighbour_blocks.get(entry as usize) else {
                    complete = false;
                    continue;
                };
                // `product` is `S_ij`'s part; the stored block is `S_ij` when
                // `i`'s pose is its row (the smaller pose and the row, or
                // the larger and not), else `S_ji = S_ijᵀ`.
                if (yi.free_pose < yj.free_pose) == pair.a_is_row {
                    subtract_block(values, &pair.slot, &product);
                } else {
                    subtract_block_transposed(values, &pair.slot, &product);
                }
            }
        }
        complete
    }

    /// `S_aa −= block`, read from `block`'s upper triangle (as the dense
    /// path does) into the stored lower triangle; false without a diagonal
    /// block.
    #[inline]
    fn subtract_diagonal_upper(&self, values: &mut [f64], a: usize, block: &Matrix6<f64>) -> bool {
        let Some(slot) = self.diagonal_block(a) else {
            return false;
        };
        // Stored column c holds rows c..6; entry (r, c) takes block (c, r).
        for (c, &start) in slot.iter().enumerate() {
            for (offset, value) in values[start..start + 6 - c].iter_mut().enumerate() {
                *value -= block[(c, c + offset)];
            }
        }
        true
    }
}

/// Subtracts `block` from a stored off-diagonal block.
#[inline]
fn subtract_block(values: &mut [f64], slot: &BlockSlot<6>, block: &Matrix6<f64>) {
    for (c, &start) in slot.iter().enumerate() {
        for (value, &entry) in values[start..start + 6]
            .iter_mut()
            .zip(block.column(c).iter())
        {
            *value -= entry;
        }
    }
}

/// Subtracts `blockᵀ` from a stored off-diagonal block.
#[inline]
fn subtract_block_transposed(values: &mut [f64], slot: &BlockSlot<6>, block: &Matrix6<f64>) {
    for (c, &start) in slot.iter().enumerate() {
        for (r, value) in values[start..start + 6].iter_mut().enumerate() {
            *value -= block[(c, r)];
        }
    }
}

/// The sparse factorisation and its buffers, allocated once per bundle adjustment.
pub(super) struct SparseReducedSolver {
    cholesky: SparseCholesky,
    values: Vec<f64>,
    rhs: Vec<f64>,
}

impl SparseReducedSolver {
    /// Runs the symbolic analysis of `reduced`'s pattern (at least one free pose).
    pub fn new(reduced: &ReducedPattern) -> Result<Self, OptimError> {
        let pattern = &reduced.pattern;
        let cholesky = SparseCholesky::analyse(
            pattern.dimension(),
            &pattern.column_pointers,
            &pattern.row_indices,
        )?;
        Ok(Self {
            cholesky,
            values: vec![0.0; pattern.value_count()],
            rhs: vec![0.0; pattern.dimension()],
        })
    }

    /// Solves `(Σ parts + H_cc + μD) δc = rhs` (`rhs` in free-pose order,
    /// `−b_c` already included) into `steps`; false when `S` is not
    /// numerically positive definite or the step is not finite.
    pub fn solve<'p>(
        &mut self,
        reduced: &ReducedPattern,
        parts: impl Iterator<Item = &'p [f64]>,
        pose_hessian: &[Matrix6<f64>],
        mu: f64,
        rhs: &DVector<f64>,
        steps: &mut [Vector6<f64>],
    ) -> bool {
        self.values.fill(0.0);
        for part in parts {
            for (total, value) in self.values.iter_mut().zip(part) {
                *total += value;
            }
        }
        let positions = &reduced.pattern.block_of_node;
        for (f, h) in pose_hessian.iter().enumerate() {
            let (Some(position), Some(slot)) = (
                positions.get(f).copied().flatten(),
                reduced.diagonal_block(f),
            ) else {
                return false;
            };
            let damped = h + Matrix6::from_diagonal(&(h.diagonal().map(marquardt_scale) * mu));
            add_diagonal_block(&mut self.values, slot, &damped);
            self.rhs[6 * position..6 * position + 6]
                .copy_from_slice(rhs.fixed_rows::<6>(6 * f).as_slice());
        }
        if self
            .cholesky
            .factorise_and_solve(&self.values, &mut self.rhs)
            .is_err()
        {
            return false;
        }
        if !self.rhs.iter().all(|v| v.is_finite()) {
            return false;
        }
        for (f, step) in steps.iter_mut().enumerate() {
            let Some(position) = positions.get(f).copied().flatten() else {
                return false;
            };
            *step = Vector6::from_column_slice(&self.rhs[6 * position..6 * position + 6]);
        }
        true
    }
}
