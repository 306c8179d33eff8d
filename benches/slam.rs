//! Stereo SLAM without feature extraction: stereo matching, tracking and
//! local mapping over the 51 frames of the KITTI 06 excerpt at 1000
//! features, with the settings of `settings/KITTI04-12.yaml` (8 levels,
//! every stereo depth kept).
//!
//! The features of every frame are extracted once before timing; one
//! iteration resets the system, processes the whole excerpt and waits for
//! local mapping to finish, so the time per frame is the iteration time /
//! 51. Extractors: ORB (`orb_1000`) and SuperPoint + kd-tree ANMS
//! (`superpoint_anms_1000`, whose setup extracts 102 images on 8 levels:
//! about three minutes on a 2-core machine). Local mapping runs inline
//! (all of it on the clock, one core) or on its own thread (`*_mapping_thread`,
//! as `spslam run` does); for the threaded runs the setup also prints the
//! tracking time per frame (stereo matching + tracking, median and 95th
//! percentile) while mapping runs beside it.
//!
//! Data: `SPSLAM_DATA`, else `../shared/data` next to the crate. Without it
//! (or without the model) the benchmark is skipped with a message.
//! Run: `cargo bench --bench slam -- --warm-up-time 1 --measurement-time 20`.

use std::path::PathBuf;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion, SamplingMode};
use spslam::camera::CameraRig;
use spslam::dataset::KittiSequence;
use spslam::features::{FeatureExtractor, GrayImage, OrbConfig, OrbExtractor, SuperPointExtractor};
use spslam::mapping::MappingStepTimes;
use spslam::settings::SlamSettings;
use spslam::system::{FrameRecord, SlamSystem};
use spslam::tracking::{Frontend, SensorFeatures, SensorImages, TrackingState};

fn data_dir() -> PathBuf {
    std::env::var_os("SPSLAM_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data"))
}

/// The excerpt's images and settings, or why they are missing.
struct Excerpt {
    images: Vec<(f64, GrayImage, GrayImage)>,
    settings: SlamSettings,
}

fn load_excerpt() -> Result<Excerpt, String> {
    let seq = KittiSequence::open(data_dir().join("kitti"), "06").map_err(|e| e.to_string())?;
    let settings = SlamSettings::from_file(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/settings/KITTI04-12.yaml"
    ))
    .map_err(|e| e.to_string())?;
    let mut images = Vec::new();
    for f in seq.frames() {
        let l = GrayImage::load(&f.left).map_err(|e| e.to_string())?;
        let r = GrayImage::load(&f.right).map_err(|e| e.to_string())?;
        images.push((f.timestamp, l, r));
    }
    Ok(Excerpt { images, settings })
}

type Extractors = (Box<dyn FeatureExtractor>, Box<dyn FeatureExtractor>);
/// Builds the left and right extractors from the settings.
type MakeExtractors = fn(&SlamSettings) -> Result<Extractors, String>;

/// A system over `extractors`, and every frame's features.
fn prepare(
    excerpt: &Excerpt,
    extractors: Extractors,
) -> Result<(SlamSystem, Vec<SensorFeatures>), String> {
    let (w, h) = (excerpt.images[0].1.width(), excerpt.images[0].1.height());
    let rig = CameraRig::from_settings(&excerpt.settings, w, h).map_err(|e| e.to_string())?;
    let mut slam = SlamSystem::new(rig, Frontend::new(extractors.0, extractors.1, &rig));
    let mut features = Vec::new();
    for (i, (_, l, r)) in excerpt.images.iter().enumerate() {
        features.push(
            slam.extract(
                i,
                SensorImages::Stereo {
                    left: l.view(),
                    right: r.view(),
                },
            )
            .map_err(|e| e.to_string())?,
        );
    }
    Ok((slam, features))
}

/// Resets the system, tracks the whole excerpt (local mapping on its own
/// thread when `threaded`) and waits for mapping; panics if a frame is lost.
fn run_excerpt(
    slam: &mut SlamSystem,
    excerpt: &Excerpt,
    features: &[SensorFeatures],
    threaded: bool,
) {
    slam.reset().unwrap_or_else(|e| panic!("{e}"));
    if threaded {
        slam.spawn_mapping_thread()
            .unwrap_or_else(|e| panic!("{e}"));
    }
    for (i, ((t, l, r), f)) in excerpt.images.iter().zip(features).enumerate() {
        let record = slam
            .process_features(
                i,
                *t,
                f.clone(),
                SensorImages::Stereo {
                    left: l.view(),
                    right: r.view(),
                },
                0.0,
            )
            .unwrap_or_else(|e| panic!("frame {i}: {e}"));
        assert!(record.state == TrackingState::Ok, "frame {i} lost");
    }
    slam.finish().unwrap_or_else(|e| panic!("{e}"));
}

/// Median and 95th percentile of the per-frame tracking time (stereo
/// matching + tracking, keyframe insertion included).
fn print_tracking_percentiles(name: &str, records: &[FrameRecord]) {
    let mut ms: Vec<f64> = records
        .iter()
        .map(|r| r.timings.stereo_ms + r.timings.tracking_ms)
        .collect();
    ms.sort_by(f64::total_cmp);
    let at = |q: f64| ms[((ms.len() - 1) as f64 * q).round() as usize];
    if ms.is_empty() {
        return;
    }
    eprintln!(
        "{name}: tracking per frame (stereo + tracking) median {:.2} ms, p95 {:.2} ms ({:.2}x the median)",
        at(0.5),
        at(0.95),
        at(0.95) / at(0.5)
    );
}

/// Prints one run's mean milliseconds per frame by stage and mapping step.
fn print_breakdown(name: &str, records: &[FrameRecord]) {
    let n = records.len().max(1) as f64;
    let sum = |f: &dyn Fn(&FrameRecord) -> f64| records.iter().map(f).sum::<f64>() / n;
    let step = |f: &dyn Fn(&MappingStepTimes) -> f64| {
        sum(&|r: &FrameRecord| r.mapping.as_ref().map_or(0.0, |m| f(&m.step_ms)))
    };
    eprintln!(
        "{name}: {} keyframes / {} frames; ms per frame: stereo {:.2}, tracking {:.2}, mapping {:.2} \
         (triangulation {:.2}, fusion {:.2}, local BA {:.2}, culling {:.2})",
        records.iter().filter(|r| r.keyframe).count(),
        records.len(),
        sum(&|r: &FrameRecord| r.timings.stereo_ms),
        sum(&|r: &FrameRecord| r.timings.tracking_ms),
        sum(&|r: &FrameRecord| r.timings.mapping_ms),
        step(&|s: &MappingStepTimes| s.triangulation_ms),
        step(&|s: &MappingStepTimes| s.fusion_ms),
        step(&|s: &MappingStepTimes| s.bundle_ms),
        step(&|s: &MappingStepTimes| s.culling_ms),
    );
}

fn orb(settings: &SlamSettings) -> Result<Extractors, String> {
    let e = &settings.extractor;
    let config = OrbConfig {
        n_features: e.n_features,
        scale_factor: e.scale_factor as f32,
        n_levels: e.n_levels,
        ini_th_fast: e.ini_th_fast,
        min_th_fast: e.min_th_fast,
    };
    let make = || OrbExtractor::new(config).map_err(|e| e.to_string());
    Ok((Box::new(make()?), Box::new(make()?)))
}

/// SuperPoint as the figures in BENCHMARKS.md were taken: the fp32 network
/// on the settings' 8 ORB levels (the features only feed SLAM here; their
/// extraction is not timed).
fn superpoint(settings: &SlamSettings) -> Result<Extractors, String> {
    let mut config = settings
        .extractor
        .superpoint_config(settings.extractor.n_levels, 1);
    config.precision = spslam::features::Precision::Fp32;
    let model = config.resolved_model_path();
    if !model.exists() {
        return Err(format!("no model at {}", model.display()));
    }
    let make = || SuperPointExtractor::new(config.clone()).map_err(|e| e.to_string());
    Ok((Box::new(make()?), Box::new(make()?)))
}

fn bench_slam(c: &mut Criterion) {
    let excerpt = match load_excerpt() {
        Ok(e) => e,
        Err(e) => {
            eprintln!("slam benchmark skipped: KITTI 06 excerpt unavailable ({e})");
            return;
        }
    };
    let mut group = c.benchmark_group("kitti06_excerpt_51_frames");
    group.sampling_mode(SamplingMode::Flat);
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(20));
    let variants: [(&str, MakeExtractors); 2] =
        [("orb_1000", orb), ("superpoint_anms_1000", superpoint)];
    for (extractor, make) in variants {
        let prepared = make(&excerpt.settings).and_then(|x| prepare(&excerpt, x));
        let (mut slam, features) = match prepared {
            Ok(p) => p,
            Err(e) => {
                eprintln!("{extractor} skipped: {e}");
                continue;
            }
        };
        for threaded in [false, true] {
            let name = if threaded {
                format!("{extractor}_mapping_thread")
            } else {
                extractor.to_string()
            };
            run_excerpt(&mut slam, &excerpt, &features, threaded);
            print_breakdown(&name, slam.records());
            if threaded {
                print_tracking_percentiles(&name, slam.records());
            }
            group.bench_function(&name, |b| {
                b.iter(|| run_excerpt(&mut slam, &excerpt, &features, threaded))
            });
        }
    }
    group.finish();
}

criterion_group!(benches, bench_slam);
criterion_main!(benches);
