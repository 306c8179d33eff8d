//! Synthetic renderer: one 640×480 stereo frame of the `loop` scene
//! (frame 40, in the street canyon), without and with the depth map, on
//! every core and on one thread.
use criterion::{black_box, criterion_group, criterion_main, Criterion};
use spslam::dataset::synthetic::{SceneName, SyntheticConfig, SyntheticSequence};

fn bench(c: &mut Criterion) {
    let sequence = SyntheticSequence::new(SyntheticConfig::for_scene(SceneName::Loop))
        .unwrap_or_else(|e| panic!("{e}"));
    let mut g = c.benchmark_group("synthetic_render_640x480");
    g.sample_size(20);
    g.bench_function("stereo", |b| {
        b.iter(|| sequence.render(black_box(40), false))
    });
    g.bench_function("stereo_with_depth", |b| {
        b.iter(|| sequence.render(black_box(40), true))
    });
    let mut one_thread = SyntheticConfig::for_scene(SceneName::Loop);
    one_thread.threads = 1;
    let single = SyntheticSequence::new(one_thread).unwrap_or_else(|e| panic!("{e}"));
    g.bench_function("stereo_one_thread", |b| {
        b.iter(|| single.render(black_box(40), false))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
