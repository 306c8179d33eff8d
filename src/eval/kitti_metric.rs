//! The KITTI odometry metric, as the devkit's `evaluate_odometry.cpp` computes it.

use nalgebra::Matrix4;

use super::error::{EvalError, Result};
use super::trajectory::Trajectory;

/// The segment lengths of the devkit, in metres.
pub const KITTI_LENGTHS: [f64; 8] = [100.0, 200.0, 300.0, 400.0, 500.0, 600.0, 700.0, 800.0];

/// The devkit's stride between first frames ("every second" at 10 Hz).
pub const KITTI_STEP_SIZE: usize = 10;

/// The error of one segment.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct SegmentError {
    /// First frame of the segment.
    pub first_frame: usize,
    /// Last frame (the first whose distance exceeds the first's by `length`).
    pub last_frame: usize,
    /// Nominal segment length in metres.
    pub length: f64,
    /// Rotation error divided by the length (rad/m).
    pub r_err: f64,
    /// Translation error divided by the length (m/m).
    pub t_err: f64,
}

/// The averages over the segments of one length.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct LengthError {
    /// Segment length in metres.
    pub length: f64,
    /// Number of segments of this length.
    pub segments: usize,
    /// Mean translation error in percent.
    pub t_err_pct: f64,
    /// Mean rotation error in degrees per metre.
    pub r_err_deg_per_m: f64,
    /// Mean rotation error in degrees per 100 m.
    pub r_err_deg_per_100m: f64,
}

/// The KITTI odometry figures of a sequence.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct KittiMetric {
    /// Mean translation error over all segments, in percent.
    pub t_err_pct: f64,
    /// Mean rotation error over all segments, in degrees per metre.
    pub r_err_deg_per_m: f64,
    /// Mean rotation error over all segments, in degrees per 100 m.
    pub r_err_deg_per_100m: f64,
    /// Number of segments (all lengths).
    pub segments: usize,
    /// The figures per segment length (lengths without segments are left out).
    pub per_length: Vec<LengthError>,
}

/// The devkit's `trajectoryDistances`, accumulated in single precision like the devkit.
pub fn trajectory_distances(poses: &[Matrix4<f64>]) -> Vec<f32> {
    let mut dist: Vec<f32> = Vec::with_capacity(poses.len());
    for (i, pose) in poses.iter().enumerate() {
        if i == 0 {
            dist.push(0.0);
            continue;
        }
        let d = poses[i - 1].fixed_view::<3, 1>(0, 3) - pose.fixed_view::<3, 1>(0, 3);
        let (dx, dy, dz) = (d.x as f32, d.y as f32, d.z as f32);
        dist.push(dist[i - 1] + (dx * dx + dy * dy + dz * dz).sqrt());
    }
    dist
}

/// The devkit's `lastFrameFromSegmentLength`: the first frame from `first` on
/// whose distance exceeds `dist[first] + len`, or `None` (the devkit's −1).
pub fn last_frame_from_segment_length(dist: &[f32], first: usize, len: f32) -> Option<usize> {
    (first..dist.len()).find(|&i| dist[i] > dist[first] + len)
}

/// The devkit's `rotationError`: `acos(clamp((trace − 1)/2, −1, 1))`.
pub fn rotation_error(pose_error: &Matrix4<f64>) -> f64 {
    let m = pose_error;
    let d = 0.5 * (m[(0, 0)] + m[(1, 1)] + m[(2, 2)] - 1.0);
    d.clamp(-1.0, 1.0).acos()
}

/// The devkit's `translationError`: the norm of the translation column.
pub fn translation_error(pose_error: &Matrix4<f64>) -> f64 {
    pose_error.fixed_view::<3, 1>(0, 3).norm()
}

/// The devkit's `calcSequenceErrors`: every segment error, on the 4×4 pose
/// matrices as read (general inverses, as the devkit's `Matrix::inv`).
pub fn segment_errors(ground_truth: &[Matrix4<f64>], result: &[Matrix4<f64>]) -> Vec<SegmentError> {
    let inv = |m: &Matrix4<f64>| m.try_inverse().unwrap_or_else(Matrix4::zeros);
    let dist = trajectory_distances(ground_truth);
    let mut errors = Vec::new();
    for first in (0..ground_truth.len()).step_by(KITTI_STEP_SIZE) {
        for &length in &KITTI_LENGTHS {
            let Some(last) = last_frame_from_segment_length(&dist, first, length as f32) else {
                continue;
            };
            let delta_gt = inv(&ground_truth[first]) * ground_truth[last];
            let delta_result = inv(&result[first]) * result[last];
            let pose_error = inv(&delta_result) * delta_gt;
            errors.push(SegmentError {
                first_frame: first,
                last_frame: last,
                length,
                r_err: rotation_error(&pose_error) / length,
                t_err: translation_error(&pose_error) / length,
            });
        }
    }
    errors
}

fn summarize(errors: &[&SegmentError], length: f64) -> LengthError {
    let n = errors.len() as f64;
    let t = errors.iter().map(|e| e.t_err).sum::<f64>() / n;
    let r = errors.iter().map(|e| e.r_err).sum::<f64>() / n;
    LengthError {
        length,
        segments: errors.len(),
        t_err_pct: 100.0 * t,
        r_err_deg_per_m: r.to_degrees(),
        r_err_deg_per_100m: 100.0 * r.to_degrees(),
    }
}

/// The KITTI metric of `result` against `ground_truth` (poses correspond one to
/// one); `None` when the ground truth is too short for a 100 m segment.
pub fn kitti_metric(ground_truth: &Trajectory, result: &Trajectory) -> Result<Option<KittiMetric>> {
    if ground_truth.len() != result.len() {
        return Err(EvalError::LengthMismatch {
            reference: ground_truth.len(),
            estimate: result.len(),
        });
    }
    let errors = segment_errors(&ground_truth.matrices(), &result.matrices());
    if errors.is_empty() {
        return Ok(None);
    }
    let all: Vec<&SegmentError> = errors.iter().collect();
    let overall = summarize(&all, 0.0);
    let per_length = KITTI_LENGTHS
        .iter()
        .filter_map(|&length| {
            let these: Vec<&SegmentError> = errors.iter().filter(|e| e.length == length).collect();
            (!these.is_empty()).then(|| summarize(&these, length))
        })
        .collect();
    Ok(Some(KittiMetric {
        t_err_pct: overall.t_err_pct,
        r_err_deg_per_m: overall.r_err_deg_per_m,
        r_err_deg_per_100m: overall.r_err_deg_per_100m,
        segments: errors.len(),
        per_length,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Vector3};

    fn straight(n: usize, step: f64) -> Trajectory {
        Trajectory::from_poses(
            (0..n)
                .map(|i| Isometry3::translation(0.0, 0.0, step * i as f64))
                .collect(),
        )
    }

    #[test]
    fn identical_trajectories_have_zero_error() {
        let gt = straight(500, 1.0);
        let m = kitti_metric(&gt, &gt).unwrap().unwrap();
        assert_eq!((m.t_err_pct, m.r_err_deg_per_m), (0.0, 0.0));
        // first frames 0,10,…,490; a length L fits when first + L + 1 ≤ 499.
        let expected: usize = KITTI_LENGTHS
            .iter()
            .map(|&l| {
                (0..500)
                    .step_by(10)
                    .filter(|&f| f + l as usize + 1 < 500)
                    .count()
            })
            .sum();
        assert_eq!(m.segments, expected);
    }

    #[test]
    fn scaled_estimate_has_known_translation_error() {
        let gt = straight(400, 1.0);
        let est = straight(400, 1.02);
        let m = kitti_metric(&gt, &est).unwrap().unwrap();
        // Each segment spans L+1 metres of ground truth, with 2 % error.
        for l in &m.per_length {
            let expected = 2.0 * (l.length + 1.0) / l.length;
            assert!((l.t_err_pct - expected).abs() < 1e-9, "{l:?}");
        }
        let rotated = gt.transformed(
            &Isometry3::new(Vector3::new(3.0, 0.0, 1.0), Vector3::new(0.0, 0.4, 0.0)),
            1.0,
        );
        let r = kitti_metric(&gt, &rotated).unwrap().unwrap();
        assert!(r.t_err_pct < 1e-9 && r.r_err_deg_per_m < 1e-6);
    }

    #[test]
    fn too_short_has_no_segments() {
        let gt = straight(50, 1.0);
        assert!(kitti_metric(&gt, &gt).unwrap().is_none());
    }
}
