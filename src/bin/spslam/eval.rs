//! `spslam eval`: trajectory metrics against ground truth.

use std::path::{Path, PathBuf};

use crate::plot_plane::PlotPlaneChoice;
use anyhow::{bail, Context, Result};
use spslam::eval::{
    align, evaluate, read_kitti_with_times, read_trajectory, report::pair_trajectories,
    table::report_table, write_error_plot, write_trajectory_plot, Alignment, EvalOptions, Pairing,
    Trajectory, TrajectoryFormat, DEFAULT_MAX_DIFF,
};

#[derive(clap::Args)]
pub struct EvalArgs {
    /// Ground-truth trajectory file.
    #[arg(long)]
    gt: PathBuf,
    /// Estimated trajectory file.
    #[arg(long)]
    est: PathBuf,
    /// Format of the estimate (kitti, tum, euroc) [default: detected].
    #[arg(long)]
    format: Option<TrajectoryFormat>,
    /// Format of the ground truth [default: detected].
    #[arg(long)]
    gt_format: Option<TrajectoryFormat>,
    /// KITTI times file for the ground truth (stamps in seconds, one a line).
    #[arg(long)]
    gt_times: Option<PathBuf>,
    /// KITTI times file for the estimate.
    #[arg(long)]
    est_times: Option<PathBuf>,
    /// Maximum timestamp difference (s) when associating poses.
    #[arg(long, default_value_t = DEFAULT_MAX_DIFF)]
    max_diff: f64,
    /// Associate like evo exactly: a reference pose may pair with several
    /// estimated poses (duplicated stamps); by default each is used once.
    #[arg(long)]
    evo_duplicates: bool,
    /// Write all figures as JSON.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Write the trajectory plot (PNG) here, and the error plot beside it as `<stem>_errors.png`.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// The plot's plane: auto (the ground truth's two largest extents), xy, xz or yz.
    #[arg(long, value_enum, default_value_t = PlotPlaneChoice::Auto)]
    plot_plane: PlotPlaneChoice,
}

fn load_trajectory(
    path: &Path,
    format: Option<TrajectoryFormat>,
    times: Option<&Path>,
) -> Result<(Trajectory, TrajectoryFormat)> {
    let format = match format {
        Some(f) => f,
        None => TrajectoryFormat::detect(path)?,
    };
    let trajectory = match (format, times) {
        (TrajectoryFormat::Kitti, Some(times)) => read_kitti_with_times(path, times)?,
        (_, Some(_)) => bail!(
            "a times file only applies to KITTI files ({})",
            path.display()
        ),
        (format, None) => read_trajectory(path, format)?,
    };
    Ok((trajectory, format))
}

pub fn run_eval(args: EvalArgs) -> Result<()> {
    let (gt, gt_format) = load_trajectory(&args.gt, args.gt_format, args.gt_times.as_deref())?;
    let (est, est_format) = load_trajectory(&args.est, args.format, args.est_times.as_deref())?;
    let by_index = gt_format == TrajectoryFormat::Kitti
        && est_format == TrajectoryFormat::Kitti
        && args.gt_times.is_none()
        && args.est_times.is_none();
    let pairing = if by_index {
        Pairing::ByIndex
    } else {
        Pairing::ByTimestamp {
            max_diff: args.max_diff,
            one_to_one: !args.evo_duplicates,
        }
    };
    let options = EvalOptions {
        pairing,
        ..EvalOptions::default()
    };
    let report = evaluate(&gt, &est, &options)?;
    println!(
        "{} ({gt_format}) vs {} ({est_format})",
        args.gt.display(),
        args.est.display()
    );
    print!("{}", report_table(&report));
    if let Some(out) = &args.json {
        let file = std::fs::File::create(out)
            .with_context(|| format!("cannot create {}", out.display()))?;
        serde_json::to_writer_pretty(std::io::BufWriter::new(file), &report)
            .with_context(|| format!("cannot write {}", out.display()))?;
        println!("wrote {}", out.display());
    }
    if let Some(out) = &args.plot {
        let pair = pair_trajectories(&gt, &est, pairing)?;
        // KITTI results are plotted as given (like the devkit); others after SE3 alignment.
        let estimate = if gt_format == TrajectoryFormat::Kitti {
            pair.estimate.clone()
        } else {
            align(&pair.reference, &pair.estimate, Alignment::Se3)?
        };
        let plane = args.plot_plane.resolve(&pair.reference);
        write_trajectory_plot(&pair.reference, &estimate, out, plane)?;
        let stem = out.file_stem().and_then(|s| s.to_str()).unwrap_or("plot");
        let errors = out.with_file_name(format!("{stem}_errors.png"));
        write_error_plot(&pair.reference, &estimate, &errors)?;
        println!(
            "wrote {} ({} plane) and {}",
            out.display(),
            plane.name(),
            errors.display()
        );
    }
    Ok(())
}
