//! Local bundle adjustment and pose-only optimisation on seeded synthetic
//! scenes (`tests/common/synthetic_ba.rs`: KITTI camera, forward motion,
//! points 4–30 m deep seen by 3–6 keyframes, half stereo, 0.5 px noise).
//!
//! - `*/solve`: the default (ORB-SLAM two-stage) local BA from a realistic
//!   noisy start (free poses σ 1° and 2 cm per axis, points σ 5 cm), the
//!   first two keyframes fixed; the iteration count is printed once;
//! - `*/solve_two_threads`: the same on 2 worker threads (the default is 1);
//! - `*/one_iteration`, `*/eleven_iterations`: a single stage of exactly 1
//!   or 11 LM iterations (tolerances 0); the time per iteration is their
//!   difference over 10 (setup and the outlier pass cancel);
//! - `pose_only/...`: ORB-SLAM3's 4×10 pose optimisation of one frame
//!   from σ 1°/2 cm.
//!
//! Run: `cargo bench --bench local_ba`.
use std::time::Duration;

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use spslam::optim::local_ba::{local_bundle_adjustment, LocalBaConfig};
use spslam::optim::pose_only::{optimise_pose, PoseOnlyConfig};

#[path = "../tests/common/rng.rs"]
mod rng;

#[path = "../tests/common/synthetic_ba.rs"]
mod synthetic_ba;

use synthetic_ba::{perturb, Rng, Scene, SceneSpec};

fn scene(keyframes: usize, points: usize) -> Scene {
    Scene::new(&SceneSpec {
        keyframes,
        points,
        pixel_noise: 0.5,
        stereo_fraction: 0.5,
        ..SceneSpec::default()
    })
}

fn bench_local_ba(c: &mut Criterion, keyframes: usize, points: usize) {
    let scene = scene(keyframes, points);
    let start = scene.noisy_problem(&[0, 1], 1.0, 0.02, 0.05, 3);
    let mut probe = start.clone();
    let report = local_bundle_adjustment(&mut probe, &LocalBaConfig::default()).expect("solves");
    println!(
        "{keyframes} kf / {points} points / {} observations: stage 1 {} iterations ({} solves, {:?}), stage 2 {} iterations ({} solves, {:?}), {} outliers",
        start.observations.len(),
        report.first_stage.iterations,
        report.first_stage.solves,
        report.first_stage.termination,
        report.second_stage.iterations,
        report.second_stage.solves,
        report.second_stage.termination,
        report.outliers.len()
    );
    let fixed_iterations = |n| LocalBaConfig {
        first_stage_iterations: n,
        second_stage_iterations: 0,
        relative_cost_tolerance: 0.0,
        relative_step_tolerance: 0.0,
        ..LocalBaConfig::default()
    };
    let (one, eleven) = (fixed_iterations(1), fixed_iterations(11));
    let mut g = c.benchmark_group(format!("local_ba_{keyframes}kf_{points}pts"));
    g.sample_size(20).measurement_time(Duration::from_secs(5));
    g.bench_function("solve", |b| {
        b.iter(|| {
            let mut p = start.clone();
            local_bundle_adjustment(black_box(&mut p), &LocalBaConfig::default()).expect("solves")
        })
    });
    let two_threads = LocalBaConfig {
        threads: 2,
        ..LocalBaConfig::default()
    };
    g.bench_function("solve_two_threads", |b| {
        b.iter(|| {
            let mut p = start.clone();
            local_bundle_adjustment(black_box(&mut p), &two_threads).expect("solves")
        })
    });
    g.bench_function("one_iteration", |b| {
        b.iter(|| {
            let mut p = start.clone();
            local_bundle_adjustment(black_box(&mut p), &one).expect("solves")
        })
    });
    g.bench_function("eleven_iterations", |b| {
        b.iter(|| {
            let mut p = start.clone();
            local_bundle_adjustment(black_box(&mut p), &eleven).expect("solves")
        })
    });
    g.finish();
}

fn local_ba(c: &mut Criterion) {
    bench_local_ba(c, 10, 5000);
    bench_local_ba(c, 20, 10000);
}

fn pose_only(c: &mut Criterion) {
    let scene = scene(10, 1500);
    let (correspondences, _) = scene.correspondences(5);
    let start = perturb(&mut Rng::new(5), &scene.poses[5], 1.0, 0.02);
    println!("pose-only: {} correspondences", correspondences.len());
    let config = PoseOnlyConfig::default();
    c.bench_function("pose_only", |b| {
        b.iter(|| optimise_pose(&scene.camera, black_box(&start), &correspondences, &config))
    });
}

criterion_group!(benches, local_ba, pose_only);
criterion_main!(benches);
