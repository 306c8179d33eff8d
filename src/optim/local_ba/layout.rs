//! The observations sorted point-major (by pose within a point), the
//! point → observations index, the free-pose numbering and the point chunks
//! the worker threads take.

use std::ops::Range;

use super::problem::BundleProblem;
use crate::optim::reprojection::Observation;

/// `free_pose` of an observation whose pose is fixed.
pub(super) const FIXED_POSE: u32 = u32::MAX;

/// An observation in the point-major order.
#[derive(Debug, Clone, Copy)]
pub(super) struct SortedObservation {
    /// Index of the pose.
    pub pose: u32,
    /// Index among the free poses, or [`FIXED_POSE`].
    pub free_pose: u32,
    /// Index in the problem's observations.
    pub original: u32,
    /// The measurement.
    pub obs: Observation,
}

/// The solver's view of the problem's structure.
pub(super) struct Layout {
    /// Observations, point-major, ascending pose within a point.
    pub observations: Vec<SortedObservation>,
    /// Point `p`'s observations are `point_offsets[p]..point_offsets[p + 1]`.
    pub point_offsets: Vec<usize>,
    /// Pose index of each free pose.
    pub free_poses: Vec<usize>,
    /// Point ranges of the chunks, balanced by observation count.
    pub chunks: Vec<Range<usize>>,
    /// The most observations any point has.
    pub max_observations_per_point: usize,
}

impl Layout {
    /// Sorts the observations and numbers the free poses (`fixed` after the gauge choice).
    pub fn new(problem: &BundleProblem, fixed: &[bool], chunk_count: usize) -> Self {
        let mut free_index = vec![FIXED_POSE; fixed.len()];
        let mut free_poses = Vec::new();
        for (pose, &is_fixed) in fixed.iter().enumerate() {
            if !is_fixed {
                free_index[pose] = free_poses.len() as u32;
                free_poses.push(pose);
            }
        }
        let n_points = problem.points.len();
        let mut point_offsets = vec![0usize; n_points + 1];
        for o in &problem.observations {
            point_offsets[o.point + 1] += 1;
        }
        for p in 0..n_points {
            point_offsets[p + 1] += point_offsets[p];
        }
        let mut next = point_offsets.clone();
        let mut slots: Vec<Option<SortedObservation>> = vec![None; problem.observations.len()];
        for (original, o) in problem.observations.iter().enumerate() {
            slots[next[o.point]] = Some(SortedObservation {
                pose: o.pose as u32,
                free_pose: free_index[o.pose],
                original: original as u32,
                obs: o.obs,
            });
            next[o.point] += 1;
        }
        let mut observations: Vec<SortedObservation> = slots.into_iter().flatten().collect();
        let mut max_observations_per_point = 0;
        for p in 0..n_points {
            let range = point_offsets[p]..point_offsets[p + 1];
            max_observations_per_point = max_observations_per_point.max(range.len());
            observations[range].sort_by_key(|o| (o.pose, o.original));
        }
        let chunks = balanced_chunks(&point_offsets, chunk_count.max(1));
        Self {
            observations,
            point_offsets,
            free_poses,
            chunks,
            max_observations_per_point,
        }
    }

    /// The sorted-observation indices of point `point`.
    pub fn point_observations(&self, point: usize) -> Range<usize> {
        self.point_offsets[point]..self.point_offsets[point + 1]
    }
}

/// Splits the points into `count` contiguous ranges with about equal
/// observation counts (some may be empty).
fn balanced_chunks(point_offsets: &[usize], count: usize) -> Vec<Range<usize>> {
    let n_points = point_offsets.len() - 1;
    let total = point_offsets[n_points];
    let mut chunks = Vec::with_capacity(count);
    let mut start = 0;
    for c in 1..=count {
        let target = total * c / count;
        let end = if c == count {
            n_points
        } else {
            start + point_offsets[start..=n_points].partition_point(|&o| o < target)
        };
        let end = end.clamp(start, n_points);
        chunks.push(start..end);
        start = end;
    }
    chunks
}
