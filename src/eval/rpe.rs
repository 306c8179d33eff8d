//! Relative pose error (evo's `main_rpe`), over frame or path-length deltas.

use nalgebra::Isometry3;

use super::error::{EvalError, Result};
use super::stats::ErrorStats;
use super::trajectory::Trajectory;

/// The spacing of the pose pairs compared.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum RpeDelta {
    /// Pairs `delta` frames apart (evo `--delta_unit f`).
    Frames(usize),
    /// Pairs whose travelled path first reaches `delta` metres (evo `--delta_unit m`).
    Meters(f64),
}

impl RpeDelta {
    /// A key for reports: `frames_1`, `meters_100`, `meters_0.5`.
    pub fn key(&self) -> String {
        match self {
            Self::Frames(n) => format!("frames_{n}"),
            Self::Meters(m) => format!("meters_{m}"),
        }
    }
}

/// The RPE for one delta.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct RpeResult {
    /// The pair spacing.
    pub delta: RpeDelta,
    /// Number of pairs compared.
    pub pairs: usize,
    /// Translation error |t(E)| in metres.
    pub translation: ErrorStats,
    /// Rotation error angle(R(E)) in degrees.
    pub rotation_deg: ErrorStats,
}

/// A pair of pose indices `(i, j)`, `i < j`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PosePair {
    /// First index.
    pub first: usize,
    /// Second index.
    pub second: usize,
}

/// evo's `filter_pairs_by_index`: with `all_pairs`, every `(i, i+delta)`;
/// otherwise consecutive pairs of `0, delta, 2·delta, …` (evo's default).
pub fn pairs_by_index(len: usize, delta: usize, all_pairs: bool) -> Vec<PosePair> {
    if delta == 0 {
        return Vec::new();
    }
    if all_pairs {
        (0..len.saturating_sub(delta))
            .map(|i| PosePair {
                first: i,
                second: i + delta,
            })
            .collect()
    } else {
        let ids: Vec<usize> = (0..len).step_by(delta).collect();
        consecutive(&ids)
    }
}

/// evo's `filter_pairs_by_path` with `all_pairs=False`: starting at pose 0, the
/// next pose is the first at which the path travelled since the previous one
/// reaches `delta`; consecutive such poses form the pairs.
pub fn pairs_by_path(poses: &[Isometry3<f64>], delta: f64) -> Vec<PosePair> {
    if poses.is_empty() {
        return Vec::new();
    }
    let mut ids = vec![0];
    let mut path = 0.0;
    for i in 1..poses.len() {
        path += (poses[i].translation.vector - poses[i - 1].translation.vector).norm();
        if path >= delta {
            ids.push(i);
            path = 0.0;
        }
    }
    consecutive(&ids)
}

fn consecutive(ids: &[usize]) -> Vec<PosePair> {
    ids.windows(2)
        .map(|w| PosePair {
            first: w[0],
            second: w[1],
        })
        .collect()
}

/// The relative error pose of a pair: `inv(inv(Q_i)·Q_j) · (inv(P_i)·P_j)`,
/// Q the reference and P the estimate (evo's `rpe_base`).
pub fn relative_error(
    reference: &Trajectory,
    estimate: &Trajectory,
    pair: PosePair,
) -> Isometry3<f64> {
    let q = reference.poses[pair.first].inverse() * reference.poses[pair.second];
    let p = estimate.poses[pair.first].inverse() * estimate.poses[pair.second];
    q.inverse() * p
}

/// Options of [`rpe`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RpeOptions {
    /// The pair spacing.
    pub delta: RpeDelta,
    /// Frames: use every pair `(i, i+delta)` instead of consecutive ones.
    pub all_pairs: bool,
    /// Meters: measure the path on the reference (evo's `--pairs_from_reference`);
    /// by default, like evo, on the estimate.
    pub pairs_from_reference: bool,
}

impl RpeOptions {
    /// evo's defaults for a delta: consecutive pairs, path measured on the estimate.
    pub fn new(delta: RpeDelta) -> Self {
        Self {
            delta,
            all_pairs: false,
            pairs_from_reference: false,
        }
    }
}

/// The RPE of `estimate` against `reference` (poses correspond one to one);
/// `None` when no pair fits in the trajectory.
pub fn rpe(
    reference: &Trajectory,
    estimate: &Trajectory,
    options: RpeOptions,
) -> Result<Option<RpeResult>> {
    if reference.len() != estimate.len() {
        return Err(EvalError::LengthMismatch {
            reference: reference.len(),
            estimate: estimate.len(),
        });
    }
    let pairs = match options.delta {
        RpeDelta::Frames(n) => pairs_by_index(reference.len(), n, options.all_pairs),
        RpeDelta::Meters(m) => {
            let source = if options.pairs_from_reference {
                reference
            } else {
                estimate
            };
            pairs_by_path(&source.poses, m)
        }
    };
    let errors: Vec<Isometry3<f64>> = pairs
        .iter()
        .map(|&pair| relative_error(reference, estimate, pair))
        .collect();
    let translation: Vec<f64> = errors.iter().map(|e| e.translation.vector.norm()).collect();
    let rotation: Vec<f64> = errors
        .iter()
        .map(|e| e.rotation.angle().to_degrees())
        .collect();
    let (Some(translation), Some(rotation_deg)) =
        (ErrorStats::new(&translation), ErrorStats::new(&rotation))
    else {
        return Ok(None);
    };
    Ok(Some(RpeResult {
        delta: options.delta,
        pairs: pairs.len(),
        translation,
        rotation_deg,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    fn line(n: usize, step: f64) -> Trajectory {
        Trajectory::from_poses(
            (0..n)
                .map(|i| Isometry3::translation(step * i as f64, 0.0, 0.0))
                .collect(),
        )
    }

    #[test]
    fn pair_selection_matches_evo() {
        let ids = |p: Vec<PosePair>| p.iter().map(|p| (p.first, p.second)).collect::<Vec<_>>();
        assert_eq!(ids(pairs_by_index(7, 3, false)), vec![(0, 3), (3, 6)]);
        assert_eq!(ids(pairs_by_index(5, 3, true)), vec![(0, 3), (1, 4)]);
        assert_eq!(
            ids(pairs_by_path(&line(8, 0.4).poses, 1.0)),
            vec![(0, 3), (3, 6)]
        );
    }

    #[test]
    fn identical_and_offset_trajectories_have_zero_rpe() {
        let reference = line(30, 0.5);
        let moved = reference.transformed(
            &Isometry3::new(Vector3::new(5.0, 1.0, 2.0), Vector3::new(0.1, 0.2, 0.3)),
            1.0,
        );
        for delta in [
            RpeDelta::Frames(1),
            RpeDelta::Frames(4),
            RpeDelta::Meters(2.0),
        ] {
            let r = rpe(&reference, &moved, RpeOptions::new(delta))
                .unwrap()
                .unwrap();
            assert!(
                r.translation.max < 1e-12 && r.rotation_deg.max < 1e-9,
                "{delta:?}"
            );
        }
    }

    #[test]
    fn known_drift_per_frame() {
        let reference = line(11, 1.0);
        let estimate = line(11, 1.1);
        let r = rpe(&reference, &estimate, RpeOptions::new(RpeDelta::Frames(1)))
            .unwrap()
            .unwrap();
        assert_eq!(r.pairs, 10);
        assert!((r.translation.rmse - 0.1).abs() < 1e-12);
    }
}
