//! Extractor benchmarks on one real frame each of KITTI 06 (1226×370) and
//! EuRoC V1_01 (752×480), N = 1000:
//!
//! - `bare_session_run`: the network alone (`SuperPointModel::run` with a
//!   closure that does nothing) on the padded [1, 1, H, W] input;
//! - `end_to_end_{kdtree,ssc,none}`: `SuperPointExtractor::extract`, single level;
//! - the stages on inputs prepared once (dense outputs cached from one run):
//!   `preprocess`, `decode_nms` (threshold 0.005), `decode_nms_with_fallback`
//!   (plus the extractor's lower thresholds while < N candidates; the same
//!   as `decode_nms` when the first threshold yields N), `anms_kdtree`,
//!   `anms_ssc`, `top_n` (on the candidates the extractor hands to ANMS),
//!   `descriptors_and_angle`;
//! - `orb_opencv_1000`: OpenCV ORB with ORB-SLAM3's settings, for reference;
//! - KITTI only: `end_to_end_pyramid8_kdtree` (8 levels, scale 1.2),
//!   `bare_session_run_pyramid8` (the sum of the 8 bare runs) and
//!   `preprocess_pyramid8` (`build_pyramid` plus the padded inputs).
//!
//! Data: `SPSLAM_DATA`, else `../shared/data` next to the crate; the model:
//! `default_model_path()`. Without them the benchmarks are skipped with a
//! message. Run: `cargo bench --bench extractor -- --warm-up-time 1 --measurement-time 5`.

#[path = "common/frames.rs"]
mod frames;

use std::path::Path;

use frames::{data_dir, frames};
use std::time::Duration;

use criterion::{black_box, criterion_group, criterion_main, Criterion, SamplingMode};
use ndarray::{Array2, Array3, Array4, ArrayView4};
use opencv::core::{Mat, Vector};
use opencv::features2d::{Feature2DTrait, ORB_ScoreType, ORB};
use spslam::features::anms::{anms_kdtree, anms_ssc, select_top_n, Candidate, SSC_TOLERANCE};
use spslam::features::descriptors::sample_descriptors;
use spslam::features::model::{fill_padded_input, SuperPointModel};
use spslam::features::nms::{nms_candidates, ValidRegion};
use spslam::features::orientation::CircularPatch;
use spslam::features::periodic::{reject_low_contrast, LatticeMask};
use spslam::features::pyramid::{build_pyramid, ScaleTables};
use spslam::features::{
    default_model_path, AnmsMethod, ExtractorConfig, GrayImage, GrayImageView,
    PeriodicFilterConfig, SuperPointExtractor,
};

const N_FEATURES: usize = 1000;
const THRESHOLD: f32 = 0.005;
/// The extractor's default fallback threshold (ORB-SLAM3's minThFAST 7 / 4000).
const MIN_THRESHOLD: f32 = 0.00175;
const NMS_RADIUS: usize = 4;
const BORDER: usize = 8;

fn padded_input(image: GrayImageView<'_>) -> Array4<f32> {
    let mut buffer = Vec::new();
    let (pw, ph) = fill_padded_input(image, &mut buffer);
    Array4::from_shape_vec((1, 1, ph, pw), buffer).expect("padded buffer has the padded shape")
}

/// Periodic filter + NMS + low-contrast rejection at one threshold, as the
/// extractor does.
fn decode_nms(
    scores: &Array2<f32>,
    image: GrayImageView<'_>,
    filter: &PeriodicFilterConfig,
    threshold: f32,
    cell_max: &mut Vec<(u8, f32)>,
) -> Vec<Candidate> {
    let (w, h) = (image.width(), image.height());
    let mask = if filter.enabled && filter.lattice_min_support > 0 {
        LatticeMask::estimate(
            scores.view(),
            w,
            h,
            threshold,
            filter.lattice_min_support,
            cell_max,
        )
    } else {
        LatticeMask::empty()
    };
    let adjust = |x: usize, y: usize, s: f32| if mask.is_suppressed(x, y) { 0.0 } else { s };
    let region = ValidRegion {
        width: w,
        height: h,
        border: BORDER,
    };
    let mut candidates = nms_candidates(scores.view(), adjust, threshold, NMS_RADIUS, region);
    reject_low_contrast(&mut candidates, image, filter);
    candidates
}

/// What the extractor does on a level: `decode_nms` at `THRESHOLD`, then,
/// while fewer than `N_FEATURES` candidates, at `MIN_THRESHOLD`, /4 and /16,
/// keeping the largest set. Returns the candidates and the threshold used.
fn decode_nms_with_fallback(
    scores: &Array2<f32>,
    image: GrayImageView<'_>,
    filter: &PeriodicFilterConfig,
    cell_max: &mut Vec<(u8, f32)>,
) -> (Vec<Candidate>, f32) {
    let mut best = (
        decode_nms(scores, image, filter, THRESHOLD, cell_max),
        THRESHOLD,
    );
    for t in [MIN_THRESHOLD, MIN_THRESHOLD / 4.0, MIN_THRESHOLD / 16.0] {
        if best.0.len() >= N_FEATURES {
            break;
        }
        let retry = decode_nms(scores, image, filter, t, cell_max);
        if retry.len() > best.0.len() {
            best = (retry, t);
        }
    }
    best
}

fn extractor(anms: AnmsMethod, n_levels: usize) -> SuperPointExtractor {
    let config = ExtractorConfig {
        n_features: N_FEATURES,
        n_levels,
        scale_factor: 1.2,
        anms,
        ..Default::default()
    };
    SuperPointExtractor::new(config)
        .expect("cannot create the SuperPoint extractor (model / ONNX Runtime)")
}

fn bench_frame(c: &mut Criterion, name: &str, path: &Path, model: &mut SuperPointModel) {
    let image =
        GrayImage::load(path).unwrap_or_else(|e| panic!("cannot load {}: {e}", path.display()));
    let view = image.view();
    let (w, h) = (view.width(), view.height());
    let input = padded_input(view);

    // Dense outputs cached once, for the stage benchmarks.
    let (scores, desc): (Array2<f32>, Array3<f32>) = model
        .run(input.view(), |s, d| (s.to_owned(), d.to_owned()))
        .expect("SuperPoint inference failed on the benchmark frame");
    let filter = PeriodicFilterConfig::default();
    let mut cell_max = Vec::new();
    let first = decode_nms(&scores, view, &filter, THRESHOLD, &mut cell_max).len();
    // The candidates the extractor hands to ANMS (after its fallback thresholds).
    let (candidates, used) = decode_nms_with_fallback(&scores, view, &filter, &mut cell_max);
    let selected = anms_kdtree(&candidates, N_FEATURES);
    let points: Vec<(f32, f32)> = selected
        .iter()
        .map(|&i| (candidates[i].x, candidates[i].y))
        .collect();
    println!(
        "{name}: {w}x{h}, {first} NMS candidates at threshold {THRESHOLD}; \
         {} at threshold {used} (after the extractor's fallback) go to ANMS; {} selected",
        candidates.len(),
        points.len()
    );

    let mut g = c.benchmark_group(name);
    g.sampling_mode(SamplingMode::Flat);

    g.bench_function("bare_session_run", |b| {
        b.iter(|| {
            model
                .run(black_box(input.view()), |_, _| ())
                .expect("inference failed")
        })
    });
    for (label, method) in [
        ("end_to_end_kdtree", AnmsMethod::Kdtree),
        ("end_to_end_ssc", AnmsMethod::Ssc),
        ("end_to_end_none", AnmsMethod::None),
    ] {
        let mut ex = extractor(method, 1);
        g.bench_function(label, |b| {
            b.iter(|| ex.extract(black_box(view)).expect("extraction failed"))
        });
    }

    let mut buffer = Vec::new();
    g.bench_function("preprocess", |b| {
        b.iter(|| fill_padded_input(black_box(view), &mut buffer))
    });
    g.bench_function("decode_nms", |b| {
        b.iter(|| decode_nms(black_box(&scores), view, &filter, THRESHOLD, &mut cell_max))
    });
    g.bench_function("decode_nms_with_fallback", |b| {
        b.iter(|| decode_nms_with_fallback(black_box(&scores), view, &filter, &mut cell_max))
    });
    g.bench_function("anms_kdtree", |b| {
        b.iter(|| anms_kdtree(black_box(&candidates), N_FEATURES))
    });
    g.bench_function("anms_ssc", |b| {
        b.iter(|| anms_ssc(black_box(&candidates), N_FEATURES, SSC_TOLERANCE, w, h))
    });
    g.bench_function("top_n", |b| {
        b.iter(|| select_top_n(black_box(&candidates), N_FEATURES))
    });
    let patch = CircularPatch::new();
    let (mut out, mut scratch) = (Vec::new(), Vec::new());
    let mut angles = Vec::with_capacity(points.len());
    g.bench_function("descriptors_and_angle", |b| {
        b.iter(|| {
            out.clear();
            sample_descriptors(
                black_box(desc.view()),
                black_box(&points),
                &mut out,
                &mut scratch,
            );
            angles.clear();
            angles.extend(points.iter().map(|&(x, y)| patch.angle(view, x, y)));
            black_box((&out, &angles));
        })
    });

    // ORB-SLAM3's settings: 1000 features, scale 1.2, 8 levels, edge 31,
    // first level 0, WTA_K 2, Harris score, patch 31, FAST threshold 20.
    let mat = image
        .to_mat()
        .expect("cannot wrap the frame in an OpenCV Mat");
    let mut orb = ORB::create(
        N_FEATURES as i32,
        1.2,
        8,
        31,
        0,
        2,
        ORB_ScoreType::HARRIS_SCORE,
        31,
        20,
    )
    .expect("cannot create OpenCV ORB");
    let mut keypoints = Vector::new();
    let mut descriptors = Mat::default();
    g.bench_function("orb_opencv_1000", |b| {
        b.iter(|| {
            orb.detect_and_compute(
                black_box(&mat),
                &Mat::default(),
                &mut keypoints,
                &mut descriptors,
                false,
            )
            .expect("ORB detect_and_compute failed")
        })
    });
    g.finish();
}

/// The 8-level pyramid on the KITTI frame: end to end, the bare network runs
/// summed over the levels, and the pyramid plus padded-input build.
fn bench_pyramid8(c: &mut Criterion, name: &str, path: &Path, model: &mut SuperPointModel) {
    let image =
        GrayImage::load(path).unwrap_or_else(|e| panic!("cannot load {}: {e}", path.display()));
    let view = image.view();
    let tables = ScaleTables::new(N_FEATURES, 1.2, 8);
    let levels = build_pyramid(view, &tables).expect("cannot build the 8-level pyramid");
    let inputs: Vec<Array4<f32>> = levels.iter().map(|l| padded_input(l.view())).collect();
    let views: Vec<ArrayView4<'_, f32>> = inputs.iter().map(|a| a.view()).collect();

    let mut g = c.benchmark_group(name);
    g.sampling_mode(SamplingMode::Flat);
    g.bench_function("bare_session_run_pyramid8", |b| {
        b.iter(|| {
            for v in &views {
                model
                    .run(black_box(v.view()), |_, _| ())
                    .expect("inference failed");
            }
        })
    });
    let mut ex = extractor(AnmsMethod::Kdtree, 8);
    g.bench_function("end_to_end_pyramid8_kdtree", |b| {
        b.iter(|| ex.extract(black_box(view)).expect("extraction failed"))
    });
    let mut buffer = Vec::new();
    g.bench_function("preprocess_pyramid8", |b| {
        b.iter(|| {
            let levels = build_pyramid(black_box(view), &tables).expect("pyramid build failed");
            for l in &levels {
                fill_padded_input(l.view(), &mut buffer);
            }
            black_box(&buffer);
        })
    });
    g.finish();
}

fn benches(c: &mut Criterion) {
    let model_path = default_model_path();
    if !model_path.is_file() {
        eprintln!(
            "extractor bench: model not found at {} (run `make setup` or set SPSLAM_MODEL); skipping",
            model_path.display()
        );
        return;
    }
    let data = data_dir();
    let frames = frames(&data);
    if frames.iter().all(|(_, p)| p.is_none()) {
        eprintln!(
            "extractor bench: no benchmark frames under {} (set SPSLAM_DATA); skipping",
            data.display()
        );
        return;
    }
    let mut model = SuperPointModel::load(&model_path, None, 0, spslam::features::Device::Cpu)
        .expect("cannot load the SuperPoint model / ONNX Runtime (set ORT_DYLIB_PATH?)");
    for (name, path) in &frames {
        match path {
            Some(p) => bench_frame(c, name, p, &mut model),
            None => eprintln!(
                "extractor bench: frame for {name} not found under {}; skipping it",
                data.display()
            ),
        }
    }
    if let Some(kitti) = &frames[0].1 {
        bench_pyramid8(c, "kitti_1226x370_pyramid8", kitti, &mut model);
    }
}

fn config() -> Criterion {
    Criterion::default()
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(5))
}

criterion_group! {
    name = extractor_benches;
    config = config();
    targets = benches
}
criterion_main!(extractor_benches);
