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
//!   from σ 1°/2 cm;
//! - `reduced_system_crossover/{dense,sparse}/K`: the default local BA
//!   (two stages) of a window of K free poses (`synthetic_ba` scene, K + 2
//!   keyframes, 250 points per keyframe, first two fixed, from σ 1°/2 cm)
//!   on the dense and on the sparse reduced camera system (both take the
//!   same iterations): where the sparse path starts to pay
//!   ([`LocalBaConfig::sparse_min_free_poses`]);
//! - `global_ba_chain_K/...`: global-BA-sized chains of K free poses
//!   (`chain_scene`: K + 2 keyframes 0.8 m apart, heading oscillating
//!   ±0.1 rad, 30 points per keyframe each seen by 3–5 consecutive
//!   keyframes, half stereo), first two fixed, from σ 1°/2 cm and 5 cm: `sparse_solve` runs global BA's
//!   schedule (10 robust iterations, no second stage, as
//!   `loop_closing::global_ba`) on the sparse path, `dense_solve` the same
//!   on the dense path, `{sparse,dense}_one_iteration` one LM iteration on
//!   each path (the dense ones only at 300 free poses: 1,800 × 1,800 dense
//!   Cholesky; at 1,000 the dense `S` alone would take 288 MB per chunk).
//!
//! Run: `cargo bench --bench local_ba` (some groups only:
//! `cargo bench --bench local_ba -- 'reduced_system_crossover|global_ba_chain'`).
use std::time::Duration;

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use spslam::optim::local_ba::{local_bundle_adjustment, LocalBaConfig, ReducedSystemSolver};
use spslam::optim::pose_only::{optimise_pose, PoseOnlyConfig};

#[path = "../tests/common/rng.rs"]
mod rng;

#[path = "../tests/common/synthetic_ba.rs"]
mod synthetic_ba;

use synthetic_ba::{chain_scene, perturb, Rng, Scene, SceneSpec};

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

/// One robust LM iteration and no second stage, on the given path.
fn one_iteration(reduced_solver: ReducedSystemSolver) -> LocalBaConfig {
    LocalBaConfig {
        first_stage_iterations: 1,
        second_stage_iterations: 0,
        relative_cost_tolerance: 0.0,
        relative_step_tolerance: 0.0,
        reduced_solver,
        ..LocalBaConfig::default()
    }
}

fn reduced_system_crossover(c: &mut Criterion) {
    let mut g = c.benchmark_group("reduced_system_crossover");
    g.sample_size(10).measurement_time(Duration::from_secs(2));
    for keyframes in [12, 22, 32, 42, 52, 62, 82] {
        let scene = scene(keyframes, 250 * keyframes);
        let start = scene.noisy_problem(&[0, 1], 1.0, 0.02, 0.05, 3);
        for (name, reduced_solver) in [
            ("dense", ReducedSystemSolver::Dense),
            ("sparse", ReducedSystemSolver::Sparse),
        ] {
            let config = LocalBaConfig {
                reduced_solver,
                ..LocalBaConfig::default()
            };
            g.bench_function(format!("{name}/{}", keyframes - 2), |b| {
                b.iter(|| {
                    let mut p = start.clone();
                    local_bundle_adjustment(black_box(&mut p), &config).expect("solves")
                })
            });
        }
    }
    g.finish();
}

fn global_ba_chain(c: &mut Criterion) {
    for keyframes in [302, 1002] {
        let scene = chain_scene(keyframes, 30, 51);
        let start = scene.noisy_problem(&[0, 1], 1.0, 0.02, 0.05, 3);
        // loop_closing::global_ba's schedule.
        let global = LocalBaConfig {
            first_stage_iterations: 10,
            second_stage_iterations: 0,
            reduced_solver: ReducedSystemSolver::Sparse,
            ..LocalBaConfig::default()
        };
        let mut probe = start.clone();
        let report = local_bundle_adjustment(&mut probe, &global).expect("solves");
        println!(
            "chain {keyframes} kf / {} points / {} observations: {} iterations ({} solves, {:?}), cost {:.1} -> {:.1}",
            start.points.len(),
            start.observations.len(),
            report.first_stage.iterations,
            report.first_stage.solves,
            report.first_stage.termination,
            report.first_stage.initial_cost,
            report.first_stage.final_cost,
        );
        let mut g = c.benchmark_group(format!("global_ba_chain_{}", keyframes - 2));
        g.sample_size(10).measurement_time(Duration::from_secs(5));
        g.bench_function("sparse_solve", |b| {
            b.iter(|| {
                let mut p = start.clone();
                local_bundle_adjustment(black_box(&mut p), &global).expect("solves")
            })
        });
        let sparse_one = one_iteration(ReducedSystemSolver::Sparse);
        g.bench_function("sparse_one_iteration", |b| {
            b.iter(|| {
                let mut p = start.clone();
                local_bundle_adjustment(black_box(&mut p), &sparse_one).expect("solves")
            })
        });
        if keyframes <= 302 {
            let dense_global = LocalBaConfig {
                reduced_solver: ReducedSystemSolver::Dense,
                ..global
            };
            g.bench_function("dense_solve", |b| {
                b.iter(|| {
                    let mut p = start.clone();
                    local_bundle_adjustment(black_box(&mut p), &dense_global).expect("solves")
                })
            });
            let dense_one = one_iteration(ReducedSystemSolver::Dense);
            g.bench_function("dense_one_iteration", |b| {
                b.iter(|| {
                    let mut p = start.clone();
                    local_bundle_adjustment(black_box(&mut p), &dense_one).expect("solves")
                })
            });
        }
        g.finish();
    }
}

criterion_group!(
    benches,
    local_ba,
    pose_only,
    reduced_system_crossover,
    global_ba_chain
);
criterion_main!(benches);
