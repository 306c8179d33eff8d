//! `spslam run`: stereo SLAM over a KITTI, EuRoC or synthetic sequence;
//! writes the trajectories, a run report and, with ground truth, the metrics.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use opencv::imgcodecs;
use spslam::camera::StereoRig;
use spslam::dataset::{EurocSequence, KittiSequence, StereoFrame, StereoRectifier};
use spslam::eval::{
    align, evaluate, read_euroc, read_kitti, report::pair_trajectories, table::report_table,
    write_error_plot, write_kitti, write_trajectory_plot, write_tum, Alignment, EvalOptions,
    EvalReport, Pairing, PlotPlane, Trajectory, DEFAULT_MAX_DIFF,
};
use spslam::features::{
    AnmsMethod, FeatureExtractor, GrayImage, OrbConfig, OrbExtractor, SuperPointExtractor,
};
use spslam::optim::Se3;
use spslam::settings::SlamSettings;
use spslam::system::{SlamSummary, StereoSlam};
use spslam::tracking::StereoFrontend;

#[derive(clap::Args)]
pub struct RunArgs {
    /// The sequence: kitti:DIR, euroc:DIR or synth:DIR (DIR of `spslam synth --out`).
    #[arg(long)]
    dataset: String,
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
    /// Pyramid levels for the extractor [default: the settings' nLevels].
    #[arg(long)]
    levels: Option<usize>,
    /// Run local mapping inline after each keyframe (deterministic, slower)
    /// instead of on its own thread.
    #[arg(long)]
    inline_mapping: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum ExtractorChoice {
    Superpoint,
    Orb,
}

/// A stereo sequence and how to read its images.
enum Source {
    /// KITTI or a synthetic sequence in KITTI's layout.
    Kitti(KittiSequence),
    Euroc(EurocSequence, StereoRectifier),
}

impl Source {
    fn open(spec: &str) -> Result<Self> {
        let Some((kind, dir)) = spec.split_once(':') else {
            bail!("--dataset `{spec}` is not KIND:DIR (kitti:, euroc: or synth:)");
        };
        let dir = PathBuf::from(dir);
        match kind {
            "kitti" | "synth" => Ok(Self::Kitti(open_kitti_like(&dir)?)),
            "euroc" => {
                let seq = EurocSequence::open(&dir)?;
                let rectifier = StereoRectifier::from_euroc(seq.cam0(), seq.cam1())?;
                Ok(Self::Euroc(seq, rectifier))
            }
            other => bail!("unknown dataset kind `{other}` (kitti, euroc or synth)"),
        }
    }

    fn frames(&self) -> &[StereoFrame] {
        match self {
            Self::Kitti(seq) => seq.frames(),
            Self::Euroc(s, _) => s.frames(),
        }
    }

    fn is_kitti(&self) -> bool {
        matches!(self, Self::Kitti(_))
    }

    /// Settings from the calibration: KITTI's P0/P1, EuRoC's rectified
    /// camera. Every stereo depth is kept (no `Tracking.maxDepth`): points
    /// beyond `ThDepth` are ORB-SLAM3's "far" points, tracked and optimised
    /// like the others.
    fn default_settings(&self) -> SlamSettings {
        match self {
            Self::Kitti(seq) => {
                let c = seq.calibration();
                SlamSettings::rectified_stereo(c.fx, c.fy, c.cx, c.cy, c.baseline)
            }
            Self::Euroc(_, r) => {
                let mut s =
                    SlamSettings::rectified_stereo(r.fx(), r.fy(), r.cx(), r.cy(), r.baseline());
                s.camera.fps = 20.0;
                s
            }
        }
    }

    fn load(&self, frame: &StereoFrame) -> Result<(GrayImage, GrayImage)> {
        match self {
            Self::Kitti(_) => Ok((
                GrayImage::load(&frame.left)?,
                GrayImage::load(&frame.right)?,
            )),
            Self::Euroc(_, rectifier) => {
                let read = |p: &Path| -> Result<opencv::core::Mat> {
                    let text = p
                        .to_str()
                        .with_context(|| format!("non-UTF-8 path {}", p.display()))?;
                    let m = imgcodecs::imread(text, imgcodecs::IMREAD_GRAYSCALE)?;
                    Ok(m)
                };
                let pair = rectifier.rectify(&read(&frame.left)?, &read(&frame.right)?)?;
                Ok((
                    GrayImage::from_mat(&pair.left)?,
                    GrayImage::from_mat(&pair.right)?,
                ))
            }
        }
    }

    fn ground_truth(&self, frames: usize) -> Result<Option<Trajectory>> {
        match self {
            Self::Kitti(seq) => {
                let Some(path) = seq.ground_truth_path() else {
                    return Ok(None);
                };
                let gt = read_kitti(&path)?;
                let n = frames.min(gt.len());
                Ok(Some(gt.select(&(0..n).collect::<Vec<_>>())))
            }
            Self::Euroc(s, _) => match s.ground_truth_path() {
                Some(path) => Ok(Some(read_euroc(&path)?)),
                None => Ok(None),
            },
        }
    }
}

/// A KITTI-layout sequence from its own folder or a root holding `sequences/`.
fn open_kitti_like(dir: &Path) -> Result<KittiSequence> {
    if dir.join("calib.txt").is_file() {
        let name = dir.file_name().and_then(|n| n.to_str()).unwrap_or("00");
        return Ok(KittiSequence::open(dir, name)?);
    }
    let sequences = dir.join("sequences");
    let mut names: Vec<String> = std::fs::read_dir(&sequences)
        .with_context(|| format!("{} has no calib.txt nor sequences/", dir.display()))?
        .filter_map(|e| e.ok())
        .filter(|e| e.path().join("calib.txt").is_file())
        .filter_map(|e| e.file_name().to_str().map(String::from))
        .collect();
    names.sort();
    let Some(name) = names.first() else {
        bail!("no sequence with a calib.txt under {}", sequences.display());
    };
    Ok(KittiSequence::open(dir, name)?)
}

fn extractors(
    choice: ExtractorChoice,
    settings: &SlamSettings,
    levels: usize,
) -> Result<(Box<dyn FeatureExtractor>, Box<dyn FeatureExtractor>)> {
    let e = &settings.extractor;
    match choice {
        ExtractorChoice::Orb => {
            let config = OrbConfig {
                n_features: e.n_features,
                scale_factor: e.scale_factor as f32,
                n_levels: levels,
                ini_th_fast: e.ini_th_fast,
                min_th_fast: e.min_th_fast,
            };
            Ok((
                Box::new(OrbExtractor::new(config)?),
                Box::new(OrbExtractor::new(config)?),
            ))
        }
        ExtractorChoice::Superpoint => {
            // One ONNX Runtime thread pool per image; the two run in parallel.
            let cores = std::thread::available_parallelism().map_or(2, |n| n.get());
            let config = e.superpoint_config(levels, cores / 2);
            Ok((
                Box::new(SuperPointExtractor::new(config.clone())?),
                Box::new(SuperPointExtractor::new(config)?),
            ))
        }
    }
}

fn to_trajectory(poses: &[(f64, Se3)]) -> Trajectory {
    Trajectory::new(
        poses.iter().map(|(t, _)| *t).collect(),
        poses.iter().map(|(_, p)| p.to_isometry()).collect(),
    )
}

#[derive(serde::Serialize)]
struct RunReport<'a> {
    dataset: &'a str,
    extractor: &'a str,
    settings: &'a SlamSettings,
    summary: &'a SlamSummary,
    evaluation: Option<&'a EvalReport>,
    /// Final-position drift (KITTI-layout runs with ground truth).
    drift: Option<Drift>,
    frames: &'a [spslam::system::FrameRecord],
}

/// The end of a run against the ground truth, both starting at frame 0's pose.
#[derive(serde::Serialize)]
struct Drift {
    /// Distance between the final positions, metres.
    final_position_m: f64,
    /// Ground-truth path length, metres.
    path_m: f64,
    /// `final_position_m` as a percentage of `path_m`.
    percent: f64,
}

fn summary_text(dataset: &str, extractor: &str, s: &SlamSummary) -> String {
    let t = &s.mean_timings;
    format!(
        "dataset {dataset}, extractor {extractor}\n\
         frames {}: tracked {}, lost {} (tracking failures), before initialisation {}, relocalisations {}\n\
         keyframes inserted {}, live {}; map points {}\n\
         mean ms/frame: extraction {:.1}, stereo {:.1}, tracking {:.1}, mapping {:.1}\n",
        s.frames,
        s.tracked,
        s.lost,
        s.not_initialised,
        s.relocalisations,
        s.keyframes_inserted,
        s.keyframes,
        s.map_points,
        t.extraction_ms,
        t.stereo_ms,
        t.tracking_ms,
        t.mapping_ms
    )
}

/// Final-position drift of a KITTI-layout run (both trajectories start at
/// the first frame's pose).
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

/// Evaluates the run against `gt`, appends the figures to `text` and writes
/// the plots (`trajectory.png`, `trajectory_errors.png`) into `out`.
fn evaluate_run(
    source: &Source,
    gt: &Trajectory,
    trajectory: &Trajectory,
    out: &Path,
    text: &mut String,
) -> Result<(Option<EvalReport>, Option<Drift>)> {
    let pairing = if source.is_kitti() {
        Pairing::ByIndex
    } else {
        Pairing::ByTimestamp {
            max_diff: DEFAULT_MAX_DIFF,
            one_to_one: true,
        }
    };
    let drift = if source.is_kitti() {
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
            return Ok((None, drift));
        }
    };
    text.push_str(&report_table(&report));
    let pair = pair_trajectories(gt, trajectory, pairing)?;
    // KITTI-layout runs are plotted as given (from above, x–z); EuRoC after
    // SE3 alignment (x–y).
    let (estimate, plane) = if source.is_kitti() {
        (pair.estimate.clone(), PlotPlane::Xz)
    } else {
        (
            align(&pair.reference, &pair.estimate, Alignment::Se3)?,
            PlotPlane::Xy,
        )
    };
    let plot = out.join("trajectory.png");
    let errors = out.join("trajectory_errors.png");
    write_trajectory_plot(&pair.reference, &estimate, &plot, plane)?;
    write_error_plot(&pair.reference, &estimate, &errors)?;
    text.push_str(&format!(
        "plots: {} and {}\n",
        plot.display(),
        errors.display()
    ));
    Ok((Some(report), drift))
}

pub fn run_slam(args: RunArgs) -> Result<()> {
    let source = Source::open(&args.dataset)?;
    let mut settings = match &args.settings {
        Some(path) => SlamSettings::from_file(path)?,
        None => source.default_settings(),
    };
    if let Some(anms) = args.anms {
        settings.extractor.anms = anms;
    }
    let frames: Vec<StereoFrame> = source
        .frames()
        .iter()
        .take(args.frames.unwrap_or(usize::MAX))
        .cloned()
        .collect();
    let Some(first) = frames.first() else {
        bail!("the sequence has no frames");
    };
    let (probe, _) = source.load(first)?;
    let rig = StereoRig::from_settings(&settings, probe.width(), probe.height())?;
    let levels = args.levels.unwrap_or(settings.extractor.n_levels);
    let (left, right) = extractors(args.extractor, &settings, levels)?;
    let frontend = StereoFrontend::new(left, right, &rig);
    let mut slam = StereoSlam::new(rig, frontend);
    if let Some(mapper) = slam.mapper_mut() {
        mapper.bundle_adjustment = !args.no_local_ba;
        mapper.keyframe_culling = !args.no_keyframe_culling;
    }
    if !args.inline_mapping {
        slam.spawn_mapping_thread()?;
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;

    let bar = ProgressBar::new(frames.len() as u64);
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} frames, {elapsed} ({eta} left) {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    for (index, frame) in frames.iter().enumerate() {
        let (l, r) = source.load(frame)?;
        let record = slam.process(index, frame.timestamp, l.view(), r.view())?;
        bar.set_message(format!("{:?}, {} inliers", record.state, record.inliers));
        bar.inc(1);
    }
    slam.finish()?;
    bar.finish();

    let trajectory = to_trajectory(&slam.trajectory()?);
    let keyframes = to_trajectory(&slam.keyframe_trajectory()?);
    let (trajectory_path, keyframes_path) = if source.is_kitti() {
        let p = args.out.join("trajectory_kitti.txt");
        write_kitti(&p, &trajectory)?;
        let k = args.out.join("keyframes_tum.txt");
        write_tum(&k, &keyframes)?;
        (p, k)
    } else {
        let p = args.out.join("trajectory_tum.txt");
        write_tum(&p, &trajectory)?;
        let k = args.out.join("keyframes_tum.txt");
        write_tum(&k, &keyframes)?;
        (p, k)
    };
    let summary = slam.summary()?;
    let extractor = slam.extractor_name().to_string();
    let mut text = summary_text(&args.dataset, &extractor, &summary);
    let (evaluation, drift) = match source.ground_truth(frames.len())? {
        Some(gt) => evaluate_run(&source, &gt, &trajectory, &args.out, &mut text)?,
        None => (None, None),
    };
    print!("{text}");
    std::fs::write(args.out.join("report.txt"), &text)?;
    let report = RunReport {
        dataset: &args.dataset,
        extractor: &extractor,
        settings: &settings,
        summary: &summary,
        evaluation: evaluation.as_ref(),
        drift,
        frames: slam.records(),
    };
    let json = args.out.join("report.json");
    let file = std::fs::File::create(&json)
        .with_context(|| format!("cannot create {}", json.display()))?;
    serde_json::to_writer_pretty(std::io::BufWriter::new(file), &report)?;
    println!(
        "wrote {}, {}, {} and {}",
        trajectory_path.display(),
        keyframes_path.display(),
        args.out.join("report.txt").display(),
        json.display()
    );
    Ok(())
}
