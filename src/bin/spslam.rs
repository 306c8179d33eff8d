//! The `spslam` command line.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand};
use spslam::eval::{
    align, evaluate, read_kitti_with_times, read_trajectory, report::pair_trajectories,
    table::report_table, write_error_plot, write_trajectory_plot, Alignment, EvalOptions, Pairing,
    PlotPlane, Trajectory, TrajectoryFormat, DEFAULT_MAX_DIFF,
};
use spslam::features::draw::write_keypoint_image;
use spslam::features::periodic::dominant_phase_fraction;
use spslam::features::{AnmsMethod, ExtractorConfig, Features, GrayImage, SuperPointExtractor};

#[derive(Parser)]
#[command(
    name = "spslam",
    version,
    about = "SuperPoint-SLAM3 in Rust: SuperPoint + ANMS features and SLAM"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Extract SuperPoint + ANMS keypoints and descriptors from images.
    Extract(ExtractArgs),
    /// Evaluate an estimated trajectory against ground truth (KITTI metric, ATE, RPE).
    Eval(EvalArgs),
}

#[derive(clap::Args)]
struct EvalArgs {
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
}

#[derive(clap::Args)]
struct ExtractArgs {
    /// Image files (any format OpenCV reads; colour is converted to gray).
    #[arg(required = true)]
    images: Vec<PathBuf>,
    /// Number of keypoints over all pyramid levels.
    #[arg(long, default_value_t = 1000)]
    features: usize,
    /// Keypoint selection: kdtree (the paper's ANMS), ssc (Bailo et al.), none (top-N by score).
    #[arg(long, default_value = "kdtree")]
    anms: AnmsMethod,
    /// Pyramid levels (1 = single level).
    #[arg(long, default_value_t = 1)]
    levels: usize,
    /// Scale factor between pyramid levels.
    #[arg(long, default_value_t = 1.2)]
    scale_factor: f32,
    /// Detection threshold on the keypoint probability.
    #[arg(long, default_value_t = 0.005)]
    threshold: f32,
    /// NMS radius in pixels.
    #[arg(long, default_value_t = 4)]
    nms_radius: usize,
    /// Turn off the periodic-artefact filter (on by default; see the README).
    #[arg(long)]
    no_periodic_filter: bool,
    /// The SuperPoint ONNX model [default: $SPSLAM_MODEL or models/superpoint.onnx].
    #[arg(long)]
    model: Option<PathBuf>,
    /// ONNX Runtime's shared library [default: $ORT_DYLIB_PATH or .deps/onnxruntime/].
    #[arg(long)]
    ort_lib: Option<PathBuf>,
    /// ONNX Runtime threads (0 = automatic).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Write keypoints, descriptors and timings as JSON (with several images, `_<image stem>` is added to the name).
    #[arg(long)]
    json: Option<PathBuf>,
    /// Write the image with the keypoints drawn (with several images, `_<image stem>` is added to the name).
    #[arg(long)]
    draw: Option<PathBuf>,
}

fn main() -> std::process::ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "warn".into()),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Extract(args) => run_extract(args),
        Command::Eval(args) => run_eval(args),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn run_extract(args: ExtractArgs) -> Result<()> {
    let defaults = ExtractorConfig::default();
    let mut config = ExtractorConfig {
        n_features: args.features,
        scale_factor: args.scale_factor,
        n_levels: args.levels,
        threshold: args.threshold,
        min_threshold: defaults.min_threshold.min(args.threshold),
        nms_radius: args.nms_radius,
        anms: args.anms,
        model_path: args.model.clone().unwrap_or(defaults.model_path.clone()),
        ort_library_path: args.ort_lib.clone(),
        threads: args.threads,
        ..defaults
    };
    config.periodic_filter.enabled = !args.no_periodic_filter;
    let mut extractor = SuperPointExtractor::new(config).context("cannot create the extractor")?;
    let several = args.images.len() > 1;
    for path in &args.images {
        let image = GrayImage::load(path)?;
        let features = extractor
            .extract(image.view())
            .with_context(|| format!("extraction failed on {}", path.display()))?;
        print_summary(path, &image, &features);
        let filter = extractor.last_periodic_report();
        println!(
            "  periodic filter: {} lattice cells cleared, {} low-contrast candidates rejected",
            filter.lattice_cells, filter.low_contrast_rejected
        );
        if let Some(out) = &args.json {
            let out = output_path(out, path, several)?;
            write_json(&out, &features)?;
            println!("  wrote {}", out.display());
        }
        if let Some(out) = &args.draw {
            let out = output_path(out, path, several)?;
            write_keypoint_image(image.view(), &features.keypoints, &out)?;
            println!("  wrote {}", out.display());
        }
    }
    Ok(())
}

fn print_summary(path: &Path, image: &GrayImage, f: &Features) {
    let t = &f.timings;
    let (phase_fraction, phase) = dominant_phase_fraction(f.keypoints.iter().map(|k| (k.x, k.y)));
    println!(
        "{}: {}x{}, {} keypoints, {}-float descriptors; most common sub-cell phase {:?} holds {:.1}%",
        path.display(),
        image.width(),
        image.height(),
        f.len(),
        f.descriptor_len,
        phase,
        100.0 * phase_fraction
    );
    println!(
        "  timing ms: preprocess {:.2} | inference {:.2} | decode+nms {:.2} | anms {:.2} | descriptors {:.2} | total {:.2}",
        t.preprocess_ms, t.inference_ms, t.decode_nms_ms, t.anms_ms, t.descriptors_ms, t.total_ms
    );
}

fn output_path(out: &Path, image: &Path, several: bool) -> Result<PathBuf> {
    if !several {
        return Ok(out.to_path_buf());
    }
    let stem = image
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("image");
    let out_stem = out.file_stem().and_then(|s| s.to_str()).unwrap_or("out");
    let ext = out.extension().and_then(|s| s.to_str()).unwrap_or("");
    if ext.is_empty() {
        bail!("output path {} needs an extension", out.display());
    }
    Ok(out.with_file_name(format!("{out_stem}_{stem}.{ext}")))
}

fn write_json(path: &Path, f: &Features) -> Result<()> {
    let descriptors: Vec<&[f32]> = f.descriptors.chunks(f.descriptor_len.max(1)).collect();
    let value = serde_json::json!({
        "keypoints": f.keypoints,
        "descriptors": descriptors,
        "descriptor_len": f.descriptor_len,
        "timing_ms": {
            "preprocess": f.timings.preprocess_ms,
            "inference": f.timings.inference_ms,
            "decode_nms": f.timings.decode_nms_ms,
            "anms": f.timings.anms_ms,
            "descriptors": f.timings.descriptors_ms,
            "total": f.timings.total_ms,
        },
    });
    let file =
        std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    serde_json::to_writer(std::io::BufWriter::new(file), &value)
        .with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
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

fn run_eval(args: EvalArgs) -> Result<()> {
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
        let (estimate, plane) = if gt_format == TrajectoryFormat::Kitti {
            (pair.estimate.clone(), PlotPlane::Xz)
        } else {
            (
                align(&pair.reference, &pair.estimate, Alignment::Se3)?,
                PlotPlane::Xy,
            )
        };
        write_trajectory_plot(&pair.reference, &estimate, out, plane)?;
        let stem = out.file_stem().and_then(|s| s.to_str()).unwrap_or("plot");
        let errors = out.with_file_name(format!("{stem}_errors.png"));
        write_error_plot(&pair.reference, &estimate, &errors)?;
        println!("wrote {} and {}", out.display(), errors.display());
    }
    Ok(())
}
