//! One keyframe-database query (cosine, covisibility groups; the sketch
//! shortlist above 256 keyframes for descriptors over 1,024 values) at
//! 5,000 and 10,000 keyframes, with raw VLAD descriptors of the three
//! codebook sizes studied (k × 256 values: k = 32, 64 (the default) and 128)
//! and PCA-whitened ones (512 and 256 values). Random unit descriptors;
//! each keyframe's covisible keyframes are its 10 neighbours in id order.
//!
//! `vlad_describe`: what a keyframe's global descriptor costs with each
//! codebook (`Vlad::compute_flat` on 1,000 random 256-float descriptors:
//! assignment to the nearest of k random centres, residual sums,
//! normalisation, and for the whitened ones the 16,384 × 512 or 256
//! projection).
use std::collections::HashSet;

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use spslam::place::global_descriptor::l2_normalise;
use spslam::place::{
    DescriptorRows, GlobalDescriptor, KeyframeDatabase, QueryOptions, SeededRng, Vlad, Whitening,
};

fn unit(rng: &mut SeededRng, dim: usize) -> Vec<f32> {
    let mut v: Vec<f32> = (0..dim).map(|_| rng.next_unit() as f32 - 0.5).collect();
    l2_normalise(&mut v);
    v
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("place_query");
    g.sample_size(10);
    for dim in [32 * 256, 64 * 256, 128 * 256, 512, 256] {
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

/// `n` random unit rows of `dim` values.
fn rows(rng: &mut SeededRng, n: usize, dim: usize) -> DescriptorRows<f32> {
    let flat = (0..n).flat_map(|_| unit(rng, dim)).collect();
    DescriptorRows::from_flat(dim, flat).unwrap()
}

fn bench_describe(c: &mut Criterion) {
    const LOCAL: usize = 256;
    let mut g = c.benchmark_group("vlad_describe");
    g.sample_size(10);
    let mut rng = SeededRng::new(7);
    let keypoints = rows(&mut rng, 1_000, LOCAL);
    for (k, whitened) in [
        (32, None),
        (64, None),
        (128, None),
        (64, Some(512)),
        (64, Some(256)),
    ] {
        let mut vlad = Vlad::new(rows(&mut rng, k, LOCAL)).unwrap();
        if let Some(out) = whitened {
            let projection = rows(&mut rng, out, k * LOCAL);
            let whitening = Whitening::from_parts(vec![0.0; k * LOCAL], projection).unwrap();
            vlad = vlad.with_whitening(whitening).unwrap();
        }
        let name = match whitened {
            None => format!("k{k}_raw_{}_dims", k * LOCAL),
            Some(out) => format!("k{k}_whitened_{out}_dims"),
        };
        g.bench_function(name, |b| {
            b.iter(|| vlad.compute_flat(black_box(keypoints.as_flat())).unwrap())
        });
    }
    g.finish();
}

criterion_group!(benches, bench, bench_describe);
criterion_main!(benches);
