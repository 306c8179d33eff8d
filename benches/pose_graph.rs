//! Pose-graph optimisation: 1,000 (SE3 only: the essential graph of a
//! 1,000-keyframe map), 2,000 and 5,000 nodes (500 per lap of a circle,
//! odometry + covisibility `i→i+2`, `i→i+3` + a loop edge to the previous lap
//! every second node: ≈3.4 edges per node), SE3 and Sim3, noisy
//! measurements and a drifting start.
//!
//! - `symbolic`: the one-off pattern build + AMD + symbolic Cholesky;
//! - `iteration`: one linearisation (assembly, one thread) + numeric
//!   factorisation + solve; `iteration_2_threads` with two assembly threads;
//! - `to_convergence`: a whole LM run from the drifting start (symbolic included).
//!
//! Before the criterion groups it prints, per problem, one run's iterations,
//! initial and final χ² and mean time per iteration.
use criterion::{black_box, criterion_group, criterion_main, Criterion};
use nalgebra::{SMatrix, SVector};
use spslam::optim::lie::{Se3, Sim3};
use spslam::optim::pose_graph::{PoseGraph, PoseGraphOptions, PoseGraphSolver};

#[path = "../tests/common/rng.rs"]
mod rng;

#[path = "../tests/common/pose_graph_problems.rs"]
mod pose_graph_problems;

use pose_graph_problems::{
    build_problem, circle_ground_truth, problem_graph, Corruption, EdgeLayout, Rng, TestGroup,
};

const NODES_PER_LAP: usize = 500;

fn graph<G: TestGroup<N>, const N: usize>(nodes: usize) -> PoseGraph<G, N> {
    let laps = nodes / NODES_PER_LAP;
    let truth = circle_ground_truth(nodes, laps, 30.0);
    let layout = EdgeLayout {
        odometry: true,
        covisibility_offsets: vec![2, 3],
        loop_stride: 2,
        laps,
    };
    let sigmas = G::sigmas(0.002, 0.01, 0.002);
    let mut drift: SVector<f64, N> = G::sigmas(0.0005, 0.005, 0.0005);
    drift[1] *= -0.5;
    let corruption = Corruption {
        noise_sigmas: sigmas,
        drift_per_step: drift,
    };
    let problem =
        build_problem::<G, N>(&truth, &layout.pairs(nodes), &corruption, &mut Rng::new(1));
    let information = SMatrix::<f64, N, N>::from_diagonal(&sigmas.map(|s| 1.0 / (s * s)));
    problem_graph(&problem, &[0], &information)
}

fn bench_problem<G: TestGroup<N>, const N: usize>(c: &mut Criterion, group: &str, nodes: usize) {
    let graph = graph::<G, N>(nodes);
    let options = PoseGraphOptions::default();
    let summary = graph.clone().optimise(&options).expect("optimises");
    println!(
        "{group}/{nodes}: {} edges, {} iterations ({:?}), chi2 {:.4e} -> {:.4e}, symbolic {:.2} ms, {:.2} ms/iteration, total {:.1} ms",
        graph.edges().len(),
        summary.iterations,
        summary.termination,
        summary.initial_chi2,
        summary.final_chi2,
        summary.symbolic_seconds * 1e3,
        summary.mean_iteration_seconds() * 1e3,
        summary.total_seconds * 1e3
    );

    let mut g = c.benchmark_group(format!("pose_graph_{group}_{nodes}"));
    g.sample_size(10);
    let mut symbolic_graph = graph.clone();
    g.bench_function("symbolic", |b| {
        b.iter(|| {
            PoseGraphSolver::new(black_box(&mut symbolic_graph), options)
                .expect("solver")
                .dimension()
        })
    });
    let mut iteration_graph = graph.clone();
    let mut solver = PoseGraphSolver::new(&mut iteration_graph, options).expect("solver");
    g.bench_function("iteration", |b| {
        b.iter(|| {
            let chi2 = solver.linearise();
            let step = solver.solve_step(black_box(1e-3)).expect("solves");
            chi2 + step[0]
        })
    });
    drop(solver);
    let two_threads = PoseGraphOptions {
        assembly_threads: 2,
        ..options
    };
    let mut solver = PoseGraphSolver::new(&mut iteration_graph, two_threads).expect("solver");
    g.bench_function("iteration_2_threads", |b| {
        b.iter(|| {
            let chi2 = solver.linearise();
            let step = solver.solve_step(black_box(1e-3)).expect("solves");
            chi2 + step[0]
        })
    });
    drop(solver);
    g.bench_function("to_convergence", |b| {
        b.iter_batched(
            || graph.clone(),
            |mut fresh| fresh.optimise(&options).expect("optimises").final_chi2,
            criterion::BatchSize::LargeInput,
        )
    });
    g.finish();
}

fn bench(c: &mut Criterion) {
    // The essential graph of a 1,000-keyframe map after a loop (issue 15's
    // target: <= 200 ms): two laps, spanning tree, covisibility edges and
    // loop edges, SE3 (stereo).
    bench_problem::<Se3, 6>(c, "se3", 1000);
    for nodes in [2000, 5000] {
        bench_problem::<Se3, 6>(c, "se3", nodes);
        bench_problem::<Sim3, 7>(c, "sim3", nodes);
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
