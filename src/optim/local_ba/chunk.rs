//! A chunk of points and its working memory: everything one worker thread
//! writes during an LM iteration, allocated once per solve.

use std::ops::Range;

use nalgebra::{DMatrix, DVector, Matrix3, Matrix6, Matrix6x3, Vector3, Vector6};

use super::blocks::ScaledBlock;
use super::layout::Layout;
use super::sparse_schur::ReducedPattern;
use crate::optim::reprojection::{PinholeStereo, PoseMatrix};

/// What the workers read during a pass (shared, read-only).
pub(super) struct PassInputs<'a> {
    /// The camera.
    pub camera: &'a PinholeStereo,
    /// The sorted observations and index.
    pub layout: &'a Layout,
    /// Per sorted observation: take part in the optimisation.
    pub active: &'a [bool],
    /// Huber kernel on (true) or plain χ² (false).
    pub robust: bool,
    /// The current points.
    pub points: &'a [Vector3<f64>],
    /// The sparse reduced system's pattern, on the sparse path.
    pub reduced_pattern: Option<&'a ReducedPattern>,
}

/// Scalars a chunk accumulates during a pass.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct ChunkSums {
    /// Kernel cost of the chunk's active observations.
    pub cost: f64,
    /// A damped point block could not be inverted (or, on the sparse path,
    /// a pose pair had no block: the pattern did not match, never expected).
    pub singular: bool,
    /// `|δp|²` over the chunk's points.
    pub step_norm_squared: f64,
    /// `δpᵀ D δp` over the chunk's points (Marquardt scaling).
    pub step_scaled_norm_squared: f64,
    /// `δp · b_p` over the chunk's points.
    pub step_dot_gradient: f64,
    /// `|X|²` over the chunk's current points.
    pub state_norm_squared: f64,
}

/// This chunk's part of `−Σ W V⁻¹ Wᵀ`.
#[derive(Debug, Clone)]
pub(super) enum ReducedPart {
    /// Dense `6k×6k` (upper block triangle only; the dense path).
    Dense(DMatrix<f64>),
    /// Lower-triangle values in the [`ReducedPattern`]'s CSC layout (the
    /// sparse path).
    Sparse(Vec<f64>),
}

/// A contiguous range of points and the working memory of their pass.
pub(super) struct PointChunk {
    /// The chunk's points.
    pub points: Range<usize>,
    /// Its sorted observations.
    pub observations: Range<usize>,
    /// Per observation: `J_poseᵀ w Ω J_point` (valid when active and the pose free).
    pub pose_point: Vec<Matrix6x3<f64>>,
    /// Per point: `Σ J_pointᵀ w Ω J_point`.
    pub point_hessian: Vec<Matrix3<f64>>,
    /// Per point: `Σ J_pointᵀ w Ω r`.
    pub point_gradient: Vec<Vector3<f64>>,
    /// Per point: `(H_pp + μD)⁻¹` of the last reduction.
    pub point_inverse: Vec<Matrix3<f64>>,
    /// Per point: the candidate after the last step.
    pub candidate_points: Vec<Vector3<f64>>,
    /// Scratch for one point's `W V⁻¹` blocks.
    pub scaled: Vec<ScaledBlock>,
    /// Per free pose: this chunk's part of `H_cc`.
    pub pose_hessian: Vec<Matrix6<f64>>,
    /// Per free pose: this chunk's part of `b_c`.
    pub pose_gradient: Vec<Vector6<f64>>,
    /// This chunk's part of `−W V⁻¹ Wᵀ`.
    pub reduced: ReducedPart,
    /// This chunk's part of `W V⁻¹ b_p`.
    pub reduced_rhs: DVector<f64>,
    /// Scalars of the last pass.
    pub sums: ChunkSums,
}

impl PointChunk {
    /// Working memory for the points `points` of `layout`; `reduced_pattern`
    /// selects the sparse path.
    pub fn new(
        layout: &Layout,
        points: Range<usize>,
        reduced_pattern: Option<&ReducedPattern>,
    ) -> Self {
        let observations = layout.point_offsets[points.start]..layout.point_offsets[points.end];
        let n_points = points.len();
        let free = layout.free_poses.len();
        Self {
            pose_point: vec![Matrix6x3::zeros(); observations.len()],
            point_hessian: vec![Matrix3::zeros(); n_points],
            point_gradient: vec![Vector3::zeros(); n_points],
            point_inverse: vec![Matrix3::zeros(); n_points],
            candidate_points: vec![Vector3::zeros(); n_points],
            scaled: Vec::with_capacity(layout.max_observations_per_point),
            pose_hessian: vec![Matrix6::zeros(); free],
            pose_gradient: vec![Vector6::zeros(); free],
            reduced: match reduced_pattern {
                Some(pattern) => ReducedPart::Sparse(vec![0.0; pattern.value_count()]),
                None => ReducedPart::Dense(DMatrix::zeros(6 * free, 6 * free)),
            },
            reduced_rhs: DVector::zeros(6 * free),
            sums: ChunkSums::default(),
            points,
            observations,
        }
    }
}

/// The poses' matrices, by pose index.
pub(super) fn pose_matrices(poses: &[crate::optim::Se3], out: &mut Vec<PoseMatrix>) {
    out.clear();
    out.extend(poses.iter().map(PoseMatrix::from_se3));
}
