//! A run's trajectory against the ground truth: the final-position drift,
//! the metrics of `spslam eval` and the plots. An incomplete run is
//! evaluated over the rows it wrote.

use std::path::Path;

use anyhow::Result;

use crate::plot_plane::PlotPlaneChoice;
use spslam::eval::{
    align, evaluate, report::pair_trajectories, table::report_table, write_error_plot,
    write_trajectory_plot_with_links, Alignment, EvalOptions, EvalReport, Pairing, Trajectory,
    DEFAULT_MAX_DIFF,
};

use spslam::camera::Sensor;
use spslam::eval::{scale_drift, ScaleDrift};

use super::source::Source;

/// What the evaluation of a run found.
#[derive(Debug, Default)]
pub struct RunEvaluation {
    /// ATE, RPE and (KITTI layout) the KITTI metric.
    pub report: Option<EvalReport>,
    /// Final-position drift (KITTI layout, metric sensors).
    pub drift: Option<Drift>,
    /// Scale drift (monocular).
    pub scale_drift: Option<ScaleDrift>,
    /// The accepted loops and merges against the ground truth (None
    /// without ground truth).
    pub links: Option<Vec<LinkTruth>>,
    /// The ground truth the run was evaluated against.
    pub ground_truth: Option<Trajectory>,
}

/// Two frames joined by a loop or a merge are the same place when their
/// true positions lie within this distance (m).
pub const SAME_PLACE_M: f64 = 10.0;

/// A link between frames farther apart than [`SAME_PLACE_M`] is still right
/// when the run's final relative pose between them agrees with the truth's
/// within this distance (m): a camera that looks along a street sees, 12 m
/// before the start, what it saw 10 m after it, and ORB-SLAM3 closes such a
/// loop too. A wrong registration leaves metres of disagreement.
pub const CONSISTENT_LINK_M: f64 = 1.0;

/// An accepted loop or merge checked against the ground truth.
#[derive(Debug, Clone, serde::Serialize)]
pub struct LinkTruth {
    /// Timestamp of the query frame, s.
    pub query_time: f64,
    /// Timestamp of the matched frame, s.
    pub match_time: f64,
    /// Distance between the two frames' true positions, m.
    pub distance_m: f64,
    /// Whether they are the same place (`distance_m` ≤ [`SAME_PLACE_M`]).
    pub same_place: bool,
    /// How far the run's final relative translation between the two frames
    /// is from the truth's, m. A monocular run's is first brought to the
    /// truth's units by its local scale ([`local_scale`]); `None` where
    /// that scale is not known.
    pub relative_error_m: Option<f64>,
    /// Whether the link is right: the same place, or a relative pose that
    /// agrees with the truth within [`CONSISTENT_LINK_M`].
    pub correct: bool,
}

/// The index of the timestamp nearest to `t`.
fn nearest(timestamps: &[f64], t: f64) -> Option<usize> {
    (0..timestamps.len()).min_by(|&a, &b| {
        (timestamps[a] - t)
            .abs()
            .total_cmp(&(timestamps[b] - t).abs())
    })
}

/// The ground-truth row of the estimate's timestamp `t`: KITTI-layout
/// ground truth is paired with the estimate by row (its "timestamps" are
/// row numbers), other ground truth by time.
pub fn ground_truth_row(
    gt: &Trajectory,
    estimate: &Trajectory,
    by_index: bool,
    t: f64,
) -> Option<usize> {
    if by_index {
        nearest(&estimate.timestamps, t).filter(|&i| i < gt.len())
    } else {
        nearest(&gt.timestamps, t)
    }
}

/// Rows on either side of a linked frame over which a monocular run's
/// local scale is measured ([`local_scale`]).
pub const LOCAL_SCALE_ROWS: usize = 10;

/// Path length along `positions` over the rows `around ± LOCAL_SCALE_ROWS`.
fn path_around(positions: &[nalgebra::Vector3<f64>], around: usize) -> f64 {
    let start = around.saturating_sub(LOCAL_SCALE_ROWS);
    let end = (around + LOCAL_SCALE_ROWS).min(positions.len().saturating_sub(1));
    (start..end)
        .map(|i| (positions[i + 1] - positions[i]).norm())
        .sum()
}

/// A monocular run's scale at a link (ground-truth metres per unit of the
/// estimate): the true path length over the estimate's, both over
/// [`LOCAL_SCALE_ROWS`] rows either side of the two linked frames
/// (`(gt row, estimate row)` each). Its scale drifts, so a whole-run
/// alignment's scale would misjudge a link's length by the drift; `None`
/// when the estimate did not move there.
fn local_scale(gt: &Trajectory, estimate: &Trajectory, ends: [(usize, usize); 2]) -> Option<f64> {
    let positions =
        |t: &Trajectory| -> Vec<_> { t.poses.iter().map(|p| p.translation.vector).collect() };
    let (truth, run) = (positions(gt), positions(estimate));
    let true_path: f64 = ends.iter().map(|(g, _)| path_around(&truth, *g)).sum();
    let run_path: f64 = ends.iter().map(|(_, e)| path_around(&run, *e)).sum();
    (run_path > 0.0 && true_path.is_finite()).then(|| true_path / run_path)
}

/// Each link (query, match timestamps of the estimate) against the ground
/// truth ([`ground_truth_row`]); a monocular run's (`metric` false) at its
/// local scale ([`local_scale`]).
fn link_truth(
    gt: &Trajectory,
    estimate: &Trajectory,
    links: &[(f64, f64)],
    by_index: bool,
    metric: bool,
) -> Vec<LinkTruth> {
    let gt_index = |t: f64| ground_truth_row(gt, estimate, by_index, t);
    links
        .iter()
        .filter_map(|&(query_time, match_time)| {
            let (q, m) = (gt_index(query_time)?, gt_index(match_time)?);
            let distance_m =
                (gt.poses[q].translation.vector - gt.poses[m].translation.vector).norm();
            let (eq, em) = (
                nearest(&estimate.timestamps, query_time)?,
                nearest(&estimate.timestamps, match_time)?,
            );
            let scale = if metric {
                Some(1.0)
            } else {
                local_scale(gt, estimate, [(q, eq), (m, em)])
            };
            let relative_error_m = scale.map(|scale| {
                let truth = gt.poses[q].inverse() * gt.poses[m];
                let run = estimate.poses[eq].inverse() * estimate.poses[em];
                (truth.translation.vector - run.translation.vector * scale).norm()
            });
            let same_place = distance_m <= SAME_PLACE_M;
            Some(LinkTruth {
                query_time,
                match_time,
                distance_m,
                same_place,
                relative_error_m,
                correct: same_place || relative_error_m.is_some_and(|e| e <= CONSISTENT_LINK_M),
            })
        })
        .collect()
}

/// The end of a run against the ground truth, both starting at frame 0's pose.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Drift {
    /// Distance between the final positions, metres.
    pub final_position_m: f64,
    /// Ground-truth path length, metres.
    pub path_m: f64,
    /// `final_position_m` as a percentage of `path_m`.
    pub percent: f64,
}

/// Final-position drift of a KITTI-layout run (both trajectories start at
/// the first frame's pose), over the frames both have.
fn final_drift(gt: &Trajectory, estimate: &Trajectory) -> Option<Drift> {
    let n = gt.len().min(estimate.len());
    if n < 2 {
        return None;
    }
    let g0 = gt.poses[0].inverse();
    let e0 = estimate.poses[0].inverse();
    let path: f64 = gt.poses[..n]
        .windows(2)
        .map(|w| (w[1].translation.vector - w[0].translation.vector).norm())
        .sum();
    let g = (g0 * gt.poses[n - 1]).translation.vector;
    let e = (e0 * estimate.poses[n - 1]).translation.vector;
    let final_position_m = (g - e).norm();
    Some(Drift {
        final_position_m,
        path_m: path,
        percent: 100.0 * final_position_m / path.max(f64::MIN_POSITIVE),
    })
}

/// Evaluates the run against `gt` (KITTI layout: the first rows of the
/// ground truth, pose by pose; EuRoC: paired by timestamp), appends the
/// figures to `text` and writes the plots (`trajectory.png`,
/// `trajectory_errors.png`) into `out`.
#[allow(clippy::too_many_arguments)]
pub fn evaluate_run(
    source: &Source,
    sensor: Sensor,
    gt: &Trajectory,
    trajectory: &Trajectory,
    out: &Path,
    links: &[(f64, f64)],
    plot_plane: PlotPlaneChoice,
    text: &mut String,
) -> Result<RunEvaluation> {
    let pairing = if source.is_kitti() {
        Pairing::ByIndex
    } else {
        Pairing::ByTimestamp {
            max_diff: DEFAULT_MAX_DIFF,
            one_to_one: true,
        }
    };
    let monocular = sensor == Sensor::Monocular;
    let links_truth = link_truth(gt, trajectory, links, source.is_kitti(), !monocular);
    if !links_truth.is_empty() {
        let describe = |l: &LinkTruth| {
            let relative = l.relative_error_m.map_or(String::new(), |e| {
                format!(", relative pose off by {e:.2} m")
            });
            format!(
                "{:.2} s -> {:.2} s ({:.1} m apart{relative})",
                l.query_time, l.match_time, l.distance_m
            )
        };
        let far_but_right: Vec<String> = links_truth
            .iter()
            .filter(|l| !l.same_place && l.correct)
            .map(describe)
            .collect();
        let false_links: Vec<String> = links_truth
            .iter()
            .filter(|l| !l.correct)
            .map(describe)
            .collect();
        text.push_str(&format!(
            "loops and merges against the ground truth: {} of {} right (the same place within {SAME_PLACE_M} m, or a relative pose within {CONSISTENT_LINK_M} m of the truth){}{}\n",
            links_truth.len() - false_links.len(),
            links_truth.len(),
            if far_but_right.is_empty() { String::new() } else { format!("; farther apart but registered right: {}", far_but_right.join(", ")) },
            if false_links.is_empty() { String::new() } else { format!("; FALSE: {}", false_links.join(", ")) }
        ));
    }
    let drift = if source.is_kitti() && !monocular {
        final_drift(gt, trajectory)
    } else {
        None
    };
    if let Some(d) = &drift {
        text.push_str(&format!(
            "final-position drift {:.3} m over a {:.1} m path ({:.2} %)\n",
            d.final_position_m, d.path_m, d.percent
        ));
    }
    let pair = pair_trajectories(gt, trajectory, pairing)?;
    let scale_drift = if monocular {
        scale_drift(&pair.reference, &pair.estimate)
    } else {
        None
    };
    if let Some(d) = &scale_drift {
        text.push_str(&format!(
            "monocular scale (path length, ground truth / estimate): first third {:.4}, last third {:.4}; scale drift {:.3}x\n",
            d.first_third, d.last_third, d.ratio
        ));
    }
    let options = EvalOptions {
        pairing,
        ..EvalOptions::default()
    };
    let report = match evaluate(gt, trajectory, &options) {
        Ok(report) => report,
        Err(e) => {
            text.push_str(&format!(
                "ATE/RPE not computed: {e} (a straight path cannot be aligned; the drift above is unaligned)\n"
            ));
            return Ok(RunEvaluation {
                report: None,
                drift,
                scale_drift,
                links: Some(links_truth),
                ground_truth: Some(gt.clone()),
            });
        }
    };
    text.push_str(&report_table(&report));
    // KITTI-layout runs are plotted as given, EuRoC and TUM after SE3
    // alignment, monocular runs after Sim3 alignment; the plane is the
    // ground truth's two largest extents unless `--plot-plane` says.
    let estimate = if monocular {
        align(&pair.reference, &pair.estimate, Alignment::Sim3)?
    } else if source.is_kitti() {
        pair.estimate.clone()
    } else {
        align(&pair.reference, &pair.estimate, Alignment::Se3)?
    };
    let plane = plot_plane.resolve(&pair.reference);
    let plot = out.join("trajectory.png");
    let errors = out.join("trajectory_errors.png");
    write_trajectory_plot_with_links(&pair.reference, &estimate, &plot, plane, links)?;
    write_error_plot(&pair.reference, &estimate, &errors)?;
    text.push_str(&format!(
        "plots ({} plane): {} and {}\n",
        plane.name(),
        plot.display(),
        errors.display()
    ));
    Ok(RunEvaluation {
        report: Some(report),
        drift,
        scale_drift,
        links: Some(links_truth),
        ground_truth: Some(gt.clone()),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Translation3, UnitQuaternion};

    fn along_x(times: &[f64], step: f64) -> Trajectory {
        Trajectory::new(
            times.to_vec(),
            (0..times.len())
                .map(|i| {
                    Isometry3::from_parts(
                        Translation3::new(step * i as f64, 0.0, 0.0),
                        UnitQuaternion::identity(),
                    )
                })
                .collect(),
        )
    }

    #[test]
    fn kitti_links_pair_by_row_and_others_by_time() {
        // KITTI layout: ground-truth "times" are row numbers, the
        // estimate's are seconds (10 fps); frame 30 (3 s) and frame 0 are
        // 30 m apart, not 3 m.
        let times: Vec<f64> = (0..40).map(|i| i as f64 * 0.1).collect();
        let rows: Vec<f64> = (0..40).map(|i| i as f64).collect();
        let (gt, estimate) = (along_x(&rows, 1.0), along_x(&times, 1.0));
        let links = [(3.0, 0.0), (0.5, 0.0)];
        let truth = link_truth(&gt, &estimate, &links, true, true);
        assert!((truth[0].distance_m - 30.0).abs() < 1e-9 && !truth[0].same_place);
        assert!((truth[1].distance_m - 5.0).abs() < 1e-9 && truth[1].same_place);
        // The estimate agrees with the truth: the far link is registered right.
        assert!(truth[0].relative_error_m.unwrap() < 1e-9 && truth[0].correct);
        // By time (TUM, EuRoC): the ground truth has real timestamps.
        let gt_timed = along_x(&times, 1.0);
        let truth = link_truth(&gt_timed, &estimate, &links, false, true);
        assert!((truth[0].distance_m - 30.0).abs() < 1e-9);
        // An estimate squeezed to half the steps puts frame 30 15 m from
        // frame 0 where the truth has 30 m: the far link is false. A
        // monocular run (scale free) is judged at its local scale, 2 here:
        // the same squeezed run is right.
        let squeezed = along_x(&times, 0.5);
        let truth = link_truth(&gt, &squeezed, &links, true, true);
        assert!((truth[0].relative_error_m.unwrap() - 15.0).abs() < 1e-9 && !truth[0].correct);
        assert!(truth[1].correct);
        let truth = link_truth(&gt, &squeezed, &links, true, false);
        assert!(truth[0].relative_error_m.unwrap() < 1e-9 && truth[0].correct);
        // A monocular run with a false jump of 5 units back at frame 21: at
        // its local scale (29 m of truth over 18.5 units) frame 30 lands
        // about 15.7 m from frame 0 where the truth has 30 m: false.
        let mut wrong = along_x(&times, 0.5);
        for pose in wrong.poses.iter_mut().skip(21) {
            pose.translation.vector.x -= 5.0;
        }
        let truth = link_truth(&gt, &wrong, &links, true, false);
        assert!((truth[0].relative_error_m.unwrap() - (30.0 - 10.0 * 29.0 / 18.5)).abs() < 1e-9);
        assert!(!truth[0].correct);
        // An estimate that stands still there has no scale: not judged right.
        let still = along_x(&times, 0.0);
        let truth = link_truth(&gt, &still, &links, true, false);
        assert!(truth[0].relative_error_m.is_none() && !truth[0].correct);
    }
}
