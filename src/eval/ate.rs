//! Absolute trajectory error: RMSE of position differences, with and without alignment.

use super::error::{EvalError, Result};
use super::stats::ErrorStats;
use super::trajectory::Trajectory;
use super::umeyama::{umeyama, Similarity};

/// How the estimate is aligned to the reference before comparing positions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Alignment {
    /// No alignment.
    None,
    /// Rotation and translation (Umeyama without scale, evo `-a`).
    Se3,
    /// Rotation, translation and scale (Umeyama with scale, evo `-as`).
    Sim3,
}

/// The ATE under one alignment.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct AteResult {
    /// The alignment used.
    pub alignment: Alignment,
    /// Statistics of the per-pose position errors (metres).
    pub stats: ErrorStats,
    /// The scale applied to the estimate (1 except for Sim3).
    pub scale: f64,
}

/// The similarity that aligns `estimate` onto `reference` (identity for [`Alignment::None`]).
pub fn alignment_transform(
    reference: &Trajectory,
    estimate: &Trajectory,
    alignment: Alignment,
) -> Result<Similarity> {
    match alignment {
        Alignment::None => Ok(Similarity {
            transform: nalgebra::Isometry3::identity(),
            scale: 1.0,
        }),
        Alignment::Se3 | Alignment::Sim3 => umeyama(
            &estimate.positions(),
            &reference.positions(),
            alignment == Alignment::Sim3,
        ),
    }
}

/// The estimate aligned onto the reference (poses correspond one to one).
pub fn align(
    reference: &Trajectory,
    estimate: &Trajectory,
    alignment: Alignment,
) -> Result<Trajectory> {
    let sim = alignment_transform(reference, estimate, alignment)?;
    Ok(estimate.transformed(&sim.transform, sim.scale))
}

/// Per-pose position errors |p_ref − p_est| (poses correspond one to one).
pub fn position_errors(reference: &Trajectory, estimate: &Trajectory) -> Vec<f64> {
    reference
        .poses
        .iter()
        .zip(&estimate.poses)
        .map(|(r, e)| (r.translation.vector - e.translation.vector).norm())
        .collect()
}

/// ATE of `estimate` against `reference` after the given alignment.
pub fn ate(
    reference: &Trajectory,
    estimate: &Trajectory,
    alignment: Alignment,
) -> Result<AteResult> {
    if reference.len() != estimate.len() {
        return Err(EvalError::LengthMismatch {
            reference: reference.len(),
            estimate: estimate.len(),
        });
    }
    let sim = alignment_transform(reference, estimate, alignment)?;
    let aligned = estimate.transformed(&sim.transform, sim.scale);
    let stats = ErrorStats::new(&position_errors(reference, &aligned)).ok_or(EvalError::NoPoses)?;
    Ok(AteResult {
        alignment,
        stats,
        scale: sim.scale,
    })
}
