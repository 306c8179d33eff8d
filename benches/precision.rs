//! fp32 vs int8 SuperPoint on the CPU, at KITTI (1226×370) and EuRoC
//! (752×480) size, one real frame each:
//!
//! - `network_{fp32,int8}`: the bare network (`SuperPointModel::run`, a
//!   closure that does nothing) on the padded input, 2 intra-op threads;
//! - `extract_{fp32,int8}`: `SuperPointExtractor::extract`, one level,
//!   1000 keypoints, kd-tree ANMS, 2 intra-op threads;
//! - KITTI only, the stereo pair as `spslam run` extracts it:
//!   `stereo_pair_parallel_int8` (two extractors with one thread each, run
//!   at once, as `Extractors`) and `stereo_pair_sequential_int8` (one
//!   extractor with two threads, left then right).
//!
//! Data: `SPSLAM_DATA`, else `../shared/data`; the models:
//! `Precision::default_model_path()`. Without them the benchmarks are
//! skipped with a message. Run: `cargo bench --bench precision`.

#[path = "common/frames.rs"]
mod frames;

use std::path::PathBuf;

use std::time::Duration;

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use ndarray::Array4;
use spslam::features::model::{fill_padded_input, SuperPointModel};
use spslam::features::{Device, ExtractorConfig, GrayImage, Precision, SuperPointExtractor};

const THREADS: usize = 2;

fn extractor(precision: Precision, threads: usize) -> SuperPointExtractor {
    SuperPointExtractor::new(ExtractorConfig {
        precision,
        device: Device::Cpu,
        threads,
        ..Default::default()
    })
    .expect("cannot create the SuperPoint extractor (model / ONNX Runtime)")
}

fn bench_size(c: &mut Criterion, name: &str, image: &GrayImage) {
    let mut group = c.benchmark_group(format!("precision/{name}"));
    let mut buffer = Vec::new();
    let (pw, ph) = fill_padded_input(image.view(), &mut buffer);
    let input = Array4::from_shape_vec((1, 1, ph, pw), buffer).expect("padded shape");
    for precision in [Precision::Fp32, Precision::Int8] {
        let mut model =
            SuperPointModel::load(&precision.default_model_path(), None, THREADS, Device::Cpu)
                .expect("cannot load the model");
        group.bench_function(format!("network_{precision}"), |b| {
            b.iter(|| {
                model
                    .run(black_box(input.view()), |_, _| ())
                    .expect("inference")
            })
        });
        let mut ex = extractor(precision, THREADS);
        group.bench_function(format!("extract_{precision}"), |b| {
            b.iter(|| ex.extract(black_box(image.view())).expect("extraction"))
        });
    }
    group.finish();
}

fn bench_stereo(c: &mut Criterion, left: &GrayImage, right: &GrayImage) {
    let mut group = c.benchmark_group("precision/kitti_1226x370_stereo");
    let (mut a, mut b) = (extractor(Precision::Int8, 1), extractor(Precision::Int8, 1));
    group.bench_function("stereo_pair_parallel_int8", |bench| {
        bench.iter(|| {
            std::thread::scope(|s| {
                let job = s.spawn(|| b.extract(right.view()).expect("right"));
                let l = a.extract(left.view()).expect("left");
                black_box((l, job.join().ok()))
            })
        })
    });
    let mut one = extractor(Precision::Int8, THREADS);
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
    let missing: Vec<PathBuf> = [Precision::Fp32, Precision::Int8]
        .iter()
        .map(|p| p.default_model_path())
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
