//! ANMS benchmarks: 10,000 random candidates in a 1226×370 image → 1,000 keypoints.
use criterion::{black_box, criterion_group, criterion_main, Criterion};
use spslam::features::anms::{anms_kdtree, anms_ssc, select_top_n, Candidate};

fn candidates() -> Vec<Candidate> {
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    let mut unit = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    (0..10_000)
        .map(|_| Candidate {
            x: unit() * 1226.0,
            y: unit() * 370.0,
            score: unit(),
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let cands = candidates();
    let mut g = c.benchmark_group("anms_10k_to_1k");
    g.bench_function("ssc", |b| {
        b.iter(|| anms_ssc(black_box(&cands), 1000, 0.1, 1226, 370))
    });
    g.bench_function("kdtree", |b| {
        b.iter(|| anms_kdtree(black_box(&cands), 1000))
    });
    g.bench_function("top_n", |b| {
        b.iter(|| select_top_n(black_box(&cands), 1000))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
