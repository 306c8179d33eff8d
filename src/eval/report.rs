//! [`EvalReport`]: every figure of an evaluation, built by [`evaluate`].

use std::collections::BTreeMap;

use super::ate::{ate, Alignment};
use super::error::Result;
use super::kitti_metric::{kitti_metric, KittiMetric};
use super::rpe::{rpe, RpeDelta, RpeOptions, RpeResult};
use super::stats::ErrorStats;
use super::sync::{associate_with, AssociatedPair, DEFAULT_MAX_DIFF};
use super::trajectory::Trajectory;

/// How the poses of the two trajectories are put in correspondence.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Pairing {
    /// Pose i with pose i (KITTI files); the lengths must agree.
    ByIndex,
    /// Nearest timestamps within `max_diff` seconds (evo's association).
    ByTimestamp {
        /// Tolerance in seconds.
        max_diff: f64,
        /// Use each stamp once (true, the default); false is evo's exact rule,
        /// which repeats a pose when a file holds duplicated stamps.
        one_to_one: bool,
    },
}

/// Options of [`evaluate`].
#[derive(Debug, Clone, PartialEq)]
pub struct EvalOptions {
    /// How poses correspond.
    pub pairing: Pairing,
    /// RPE deltas; `None` picks 1 frame and a path length suited to the sequence
    /// (100 m when the ground truth is at least 500 m long, else about a tenth of it).
    pub rpe_deltas: Option<Vec<RpeDelta>>,
}

impl Default for EvalOptions {
    fn default() -> Self {
        Self {
            pairing: Pairing::ByTimestamp {
                max_diff: DEFAULT_MAX_DIFF,
                one_to_one: true,
            },
            rpe_deltas: None,
        }
    }
}

/// ATE figures under the three alignments.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct AteReport {
    /// RMSE without alignment (m).
    pub none_rmse: f64,
    /// RMSE after SE3 Umeyama alignment (m).
    pub se3_rmse: f64,
    /// RMSE after Sim3 Umeyama alignment (m).
    pub sim3_rmse: f64,
    /// The Sim3 scale.
    pub sim3_scale: f64,
    /// All statistics without alignment.
    pub none: ErrorStats,
    /// All statistics after SE3 alignment.
    pub se3: ErrorStats,
    /// All statistics after Sim3 alignment.
    pub sim3: ErrorStats,
}

/// RPE figures for one delta.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct RpeReport {
    /// The pair spacing.
    pub delta: RpeDelta,
    /// Number of pairs.
    pub pairs: usize,
    /// Translation RMSE (m).
    pub trans_rmse: f64,
    /// Translation mean (m).
    pub trans_mean: f64,
    /// Translation median (m).
    pub trans_median: f64,
    /// Translation max (m).
    pub trans_max: f64,
    /// Rotation RMSE (deg).
    pub rot_rmse_deg: f64,
    /// Rotation mean (deg).
    pub rot_mean_deg: f64,
    /// Rotation median (deg).
    pub rot_median_deg: f64,
    /// Rotation max (deg).
    pub rot_max_deg: f64,
}

impl From<RpeResult> for RpeReport {
    fn from(r: RpeResult) -> Self {
        Self {
            delta: r.delta,
            pairs: r.pairs,
            trans_rmse: r.translation.rmse,
            trans_mean: r.translation.mean,
            trans_median: r.translation.median,
            trans_max: r.translation.max,
            rot_rmse_deg: r.rotation_deg.rmse,
            rot_mean_deg: r.rotation_deg.mean,
            rot_median_deg: r.rotation_deg.median,
            rot_max_deg: r.rotation_deg.max,
        }
    }
}

/// Everything [`evaluate`] computes.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct EvalReport {
    /// How poses were put in correspondence.
    pub pairing: Pairing,
    /// Poses in the reference.
    pub reference_poses: usize,
    /// Poses in the estimate.
    pub estimate_poses: usize,
    /// Corresponding pose pairs evaluated.
    pub matched_poses: usize,
    /// Path length of the matched ground truth (m).
    pub path_length_m: f64,
    /// The KITTI odometry metric; `None` when no 100 m segment fits.
    pub kitti: Option<KittiMetric>,
    /// Absolute trajectory error.
    pub ate: AteReport,
    /// Relative pose error, keyed `frames_N` / `meters_D`.
    pub rpe: BTreeMap<String, RpeReport>,
}

/// Puts the poses of `reference` and `estimate` in correspondence.
pub fn pair_trajectories(
    reference: &Trajectory,
    estimate: &Trajectory,
    pairing: Pairing,
) -> Result<AssociatedPair> {
    match pairing {
        Pairing::ByIndex => {
            if reference.len() != estimate.len() {
                return Err(super::EvalError::LengthMismatch {
                    reference: reference.len(),
                    estimate: estimate.len(),
                });
            }
            Ok(AssociatedPair {
                reference: reference.clone(),
                estimate: estimate.clone(),
            })
        }
        Pairing::ByTimestamp {
            max_diff,
            one_to_one,
        } => associate_with(reference, estimate, max_diff, one_to_one),
    }
}

/// The RPE path delta for a sequence of `path_length` metres: 100 m from 500 m
/// on, else the largest of 1, 2, 5 × 10^k not above a tenth of the path.
pub fn auto_meters_delta(path_length: f64) -> f64 {
    if path_length >= 500.0 {
        return 100.0;
    }
    let target = (path_length / 10.0).max(1e-3);
    let decade = 10f64.powf(target.log10().floor());
    let step = [5.0, 2.0, 1.0]
        .into_iter()
        .find(|m| m * decade <= target)
        .unwrap_or(1.0);
    // Round to kill binary noise such as 0.30000000000000004.
    let value = step * decade;
    let digits = (-decade.log10()).max(0.0) as i32;
    let factor = 10f64.powi(digits);
    (value * factor).round() / factor
}

/// Evaluates `estimate` against the ground truth `reference`: pairs the poses,
/// then computes the KITTI metric, ATE (none / SE3 / Sim3) and RPE.
pub fn evaluate(
    reference: &Trajectory,
    estimate: &Trajectory,
    options: &EvalOptions,
) -> Result<EvalReport> {
    let pair = pair_trajectories(reference, estimate, options.pairing)?;
    let (gt, est) = (&pair.reference, &pair.estimate);
    let path_length_m = gt.path_length();
    let none = ate(gt, est, Alignment::None)?;
    let se3 = ate(gt, est, Alignment::Se3)?;
    let sim3 = ate(gt, est, Alignment::Sim3)?;
    let deltas = options.rpe_deltas.clone().unwrap_or_else(|| {
        vec![
            RpeDelta::Frames(1),
            RpeDelta::Meters(auto_meters_delta(path_length_m)),
        ]
    });
    let mut rpe_reports = BTreeMap::new();
    for delta in deltas {
        if let Some(result) = rpe(gt, est, RpeOptions::new(delta))? {
            rpe_reports.insert(delta.key(), RpeReport::from(result));
        }
    }
    Ok(EvalReport {
        pairing: options.pairing,
        reference_poses: reference.len(),
        estimate_poses: estimate.len(),
        matched_poses: gt.len(),
        path_length_m,
        kitti: kitti_metric(gt, est)?,
        ate: AteReport {
            none_rmse: none.stats.rmse,
            se3_rmse: se3.stats.rmse,
            sim3_rmse: sim3.stats.rmse,
            sim3_scale: sim3.scale,
            none: none.stats,
            se3: se3.stats,
            sim3: sim3.stats,
        },
        rpe: rpe_reports,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auto_delta_is_round() {
        assert_eq!(auto_meters_delta(3700.0), 100.0);
        assert_eq!(auto_meters_delta(18.0), 1.0);
        assert_eq!(auto_meters_delta(35.0), 2.0);
        assert_eq!(auto_meters_delta(60.0), 5.0);
        assert_eq!(auto_meters_delta(4.0), 0.2);
    }
}
