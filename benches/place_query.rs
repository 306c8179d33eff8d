//! One keyframe-database query (brute-force cosine, covisibility groups) at
//! 5,000 and 10,000 keyframes, with raw VLAD descriptors (64 × 256 =
//! 16,384 values) and PCA-whitened ones (512 values). Random unit
//! descriptors; each keyframe's covisible keyframes are its 10 neighbours
//! in id order.
use std::collections::HashSet;

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use spslam::place::global_descriptor::l2_normalise;
use spslam::place::{KeyframeDatabase, QueryOptions, SeededRng};

fn unit(rng: &mut SeededRng, dim: usize) -> Vec<f32> {
    let mut v: Vec<f32> = (0..dim).map(|_| rng.next_unit() as f32 - 0.5).collect();
    l2_normalise(&mut v);
    v
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("place_query");
    g.sample_size(20);
    for dim in [64 * 256, 512] {
        for n in [5_000usize, 10_000] {
            let mut rng = SeededRng::new(n as u64 + dim as u64);
            let mut db = KeyframeDatabase::new(dim).unwrap();
            for k in 0..n {
                db.insert(k, &unit(&mut rng, dim)).unwrap();
            }
            let query = unit(&mut rng, dim);
            let exclude: HashSet<usize> = (n - 10..n).collect();
            let covisible = |k: usize| -> Vec<usize> {
                (1..=5)
                    .flat_map(|d| [k.checked_sub(d), Some(k + d)])
                    .flatten()
                    .collect()
            };
            let options = QueryOptions::default();
            g.bench_function(format!("{n}_keyframes_{dim}_dims"), |b| {
                b.iter(|| {
                    db.query(black_box(&query), &exclude, covisible, &options)
                        .unwrap()
                })
            });
        }
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
