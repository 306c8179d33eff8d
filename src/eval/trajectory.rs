//! A trajectory: timestamped poses.

use nalgebra::{Isometry3, Matrix4, Point3};

/// A sequence of poses with one timestamp each (seconds; the frame index for
/// KITTI files read without a times file).
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    /// Timestamps in seconds (or frame indices), one per pose.
    pub timestamps: Vec<f64>,
    /// Poses (body or camera to world).
    pub poses: Vec<Isometry3<f64>>,
    /// The pose matrices exactly as read from a KITTI file (not re-orthonormalized),
    /// one per pose; the KITTI metric uses them to reproduce the devkit's figures.
    /// `None` for other sources, and after any transformation.
    pub raw_matrices: Option<Vec<Matrix4<f64>>>,
}

impl Trajectory {
    /// Builds a trajectory whose timestamps are the frame indices 0, 1, 2, …
    pub fn from_poses(poses: Vec<Isometry3<f64>>) -> Self {
        let timestamps = (0..poses.len()).map(|i| i as f64).collect();
        Self {
            timestamps,
            poses,
            raw_matrices: None,
        }
    }

    /// Builds a trajectory from stamps and poses (no raw matrices).
    pub fn new(timestamps: Vec<f64>, poses: Vec<Isometry3<f64>>) -> Self {
        Self {
            timestamps,
            poses,
            raw_matrices: None,
        }
    }

    /// The 4×4 pose matrices: the raw KITTI matrices when present, else the poses'.
    pub fn matrices(&self) -> Vec<Matrix4<f64>> {
        match &self.raw_matrices {
            Some(raw) if raw.len() == self.poses.len() => raw.clone(),
            _ => self.poses.iter().map(Isometry3::to_homogeneous).collect(),
        }
    }

    /// Number of poses.
    pub fn len(&self) -> usize {
        self.poses.len()
    }

    /// True when there are no poses.
    pub fn is_empty(&self) -> bool {
        self.poses.is_empty()
    }

    /// The translation parts of the poses.
    pub fn positions(&self) -> Vec<Point3<f64>> {
        self.poses
            .iter()
            .map(|p| Point3::from(p.translation.vector))
            .collect()
    }

    /// Path length travelled up to each pose (0 for the first).
    pub fn distances(&self) -> Vec<f64> {
        let mut out = Vec::with_capacity(self.len());
        let mut total = 0.0;
        for (i, pose) in self.poses.iter().enumerate() {
            if i > 0 {
                total += (pose.translation.vector - self.poses[i - 1].translation.vector).norm();
            }
            out.push(total);
        }
        out
    }

    /// Total path length.
    pub fn path_length(&self) -> f64 {
        self.distances().last().copied().unwrap_or(0.0)
    }

    /// The poses (and stamps) at the given indices, in that order.
    pub fn select(&self, indices: &[usize]) -> Self {
        Self {
            timestamps: indices.iter().map(|&i| self.timestamps[i]).collect(),
            poses: indices.iter().map(|&i| self.poses[i]).collect(),
            raw_matrices: self
                .raw_matrices
                .as_ref()
                .map(|raw| indices.iter().map(|&i| raw[i]).collect()),
        }
    }

    /// Applies `x ↦ scale·R·x + t` to every pose: positions are scaled then
    /// transformed, orientations are rotated (evo's `scale` then `transform`).
    pub fn transformed(&self, transform: &Isometry3<f64>, scale: f64) -> Self {
        let poses = self
            .poses
            .iter()
            .map(|p| {
                let mut scaled = *p;
                scaled.translation.vector *= scale;
                transform * scaled
            })
            .collect();
        Self::new(self.timestamps.clone(), poses)
    }
}
