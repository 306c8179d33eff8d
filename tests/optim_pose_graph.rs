//! Pose-graph optimisation over SE3 and Sim3 on synthetic problems with
//! known answers (`tests/common/pose_graph_problems.rs`).
//!
//! Tolerances:
//! - analytic edge Jacobians vs central differences (h = 1e-6): 1e-6 absolute;
//!   the small-residual series for `J_l⁻¹`, `J_r⁻¹` vs `LieGroup`'s: 1e-12;
//! - noise-free loops (300 poses, drifting start; node 0 fixed at ground
//!   truth): every node within 1e-6 of ground truth (`‖log(T̂ T⁻¹)‖`);
//! - noisy loops: final χ² within 5 standard deviations of its expectation
//!   `dof = N · (edges − free nodes)` (χ² distribution, std `√(2 dof)`),
//!   RMS pose error at least 10× below the initial guess's;
//! - fixed nodes: bit-identical (`==` on the pose);
//! - assembly on 3 threads vs 1: final χ² to 1e-9 relative, poses to 1e-9;
//! - dense reference (20 nodes, Gauss–Newton with numeric Jacobians and a
//!   dense Cholesky): final χ² equal to 1e-6 relative; the assembled `H`, `b`
//!   equal the reference's numeric ones to 1e-6 relative; one sparse solve
//!   equals the dense solve of the same `H`, `b` to 1e-9 relative.

mod common;

use common::pose_graph_problems::{
    build_problem, circle_ground_truth, pose_errors, problem_graph, rms, Corruption, EdgeLayout,
    Problem, Rng, TestGroup,
};
use nalgebra::{DMatrix, DVector, SMatrix, SVector, UnitQuaternion, Vector3};
use spslam::optim::error::OptimError;
use spslam::optim::lie::{LieGroup, Se3, Sim3};
use spslam::optim::pose_graph::residual::{edge_residual, inverse_jacobians, linearise_edge};
use spslam::optim::pose_graph::{
    Algorithm, PoseGraph, PoseGraphEdge, PoseGraphOptions, PoseGraphSolver, RobustKernel,
    Termination,
};

fn random_tangent<const N: usize>(rng: &mut Rng, scale: f64) -> SVector<f64, N> {
    SVector::<f64, N>::from_fn(|_, _| (rng.uniform() * 2.0 - 1.0) * scale)
}

fn loop_layout() -> EdgeLayout {
    EdgeLayout {
        odometry: true,
        covisibility_offsets: vec![2],
        loop_stride: 3,
        laps: 1,
    }
}

fn drift<G: TestGroup<N>, const N: usize>(
    rotation: f64,
    translation: f64,
    log_scale: f64,
) -> SVector<f64, N> {
    // A bias on every component: yaw/pitch/roll, x/y/z and (Sim3) scale.
    let mut bias = G::sigmas(rotation, translation, log_scale);
    bias[1] *= -0.5;
    bias[4] *= -0.7;
    bias
}

// ---------------------------------------------------------------- Jacobians

fn check_jacobians<G: TestGroup<N>, const N: usize>(residual_scale: f64) {
    let mut rng = Rng::new(7);
    let h = 1e-6;
    for _ in 0..50 {
        let from = G::exp(&random_tangent(&mut rng, 1.0));
        let to = G::exp(&random_tangent(&mut rng, 1.0));
        // Measurement near the true relative pose: residual of size ~residual_scale.
        let exact = to.compose(&from.inverse());
        let measurement = G::exp(&random_tangent(&mut rng, residual_scale)).compose(&exact);
        let linear = linearise_edge(&measurement, &from, &to);
        for k in 0..N {
            let mut delta = SVector::<f64, N>::zeros();
            delta[k] = h;
            let numeric_from = (edge_residual(&measurement, &from.perturb_left(&delta), &to)
                - edge_residual(&measurement, &from.perturb_left(&(-delta)), &to))
                / (2.0 * h);
            let numeric_to = (edge_residual(&measurement, &from, &to.perturb_left(&delta))
                - edge_residual(&measurement, &from, &to.perturb_left(&(-delta))))
                / (2.0 * h);
            let error_from = (linear.jacobian_from.column(k) - numeric_from).amax();
            let error_to = (linear.jacobian_to.column(k) - numeric_to).amax();
            assert!(error_from < 1e-6, "from column {k}: {error_from:e}");
            assert!(error_to < 1e-6, "to column {k}: {error_to:e}");
        }
    }
}

#[test]
fn se3_jacobians_match_central_differences() {
    check_jacobians::<Se3, 6>(0.05); // series path
    check_jacobians::<Se3, 6>(1.2); // exact path
}

#[test]
fn sim3_jacobians_match_central_differences() {
    check_jacobians::<Sim3, 7>(0.05);
    check_jacobians::<Sim3, 7>(1.2);
}

fn check_series<G: LieGroup<N>, const N: usize>() {
    let mut rng = Rng::new(11);
    for _ in 0..100 {
        let tangent = random_tangent::<N>(&mut rng, 0.2);
        let (left, right) = inverse_jacobians::<G, N>(&tangent);
        assert!((left - G::left_jacobian_inverse(&tangent)).amax() < 1e-12);
        assert!((right - G::right_jacobian_inverse(&tangent)).amax() < 1e-12);
    }
}

#[test]
fn inverse_jacobian_series_matches_lie_group() {
    check_series::<Se3, 6>();
    check_series::<Sim3, 7>();
}

// ---------------------------------------------------------- convergence

fn noise_free_loop<G: TestGroup<N>, const N: usize>(
    nodes: usize,
    drift_per_step: SVector<f64, N>,
) -> (Problem<G>, PoseGraph<G, N>) {
    let truth = circle_ground_truth(nodes, 1, 10.0);
    let pairs = loop_layout().pairs(nodes);
    let corruption = Corruption {
        noise_sigmas: SVector::zeros(),
        drift_per_step,
    };
    let problem = build_problem::<G, N>(&truth, &pairs, &corruption, &mut Rng::new(1));
    let graph = problem_graph(&problem, &[0], &SMatrix::identity());
    (problem, graph)
}

fn assert_converges_to_truth<G: TestGroup<N>, const N: usize>(
    problem: &Problem<G>,
    graph: &mut PoseGraph<G, N>,
    options: &PoseGraphOptions,
) {
    let before = rms(&pose_errors(graph.nodes(), &problem.ground_truth));
    let summary = graph.optimise(options).expect("optimises");
    let errors = pose_errors(graph.nodes(), &problem.ground_truth);
    let worst = errors.iter().fold(0.0f64, |a, &b| a.max(b));
    eprintln!(
        "N={N}: rms error {before:.3e} -> max {worst:.3e}; chi2 {:.3e} -> {:.3e} in {} iterations ({:?}), {:.2} ms/iteration",
        summary.initial_chi2,
        summary.final_chi2,
        summary.iterations,
        summary.termination,
        summary.mean_iteration_seconds() * 1e3
    );
    assert!(before > 1e-2, "the start should be off: {before}");
    assert!(worst < 1e-6, "max pose error {worst:e}");
}

#[test]
fn se3_loop_without_noise_converges_to_ground_truth() {
    let (problem, mut graph) = noise_free_loop::<Se3, 6>(300, drift::<Se3, 6>(0.002, 0.01, 0.0));
    assert_converges_to_truth(&problem, &mut graph, &PoseGraphOptions::default());
}

#[test]
fn sim3_loop_without_noise_converges_to_ground_truth() {
    let (problem, mut graph) =
        noise_free_loop::<Sim3, 7>(300, drift::<Sim3, 7>(0.002, 0.01, 0.002));
    assert_converges_to_truth(&problem, &mut graph, &PoseGraphOptions::default());
}

#[test]
fn se3_gauss_newton_converges_too() {
    let (problem, mut graph) = noise_free_loop::<Se3, 6>(200, drift::<Se3, 6>(0.002, 0.01, 0.0));
    let options = PoseGraphOptions {
        algorithm: Algorithm::GaussNewton,
        ..PoseGraphOptions::default()
    };
    assert_converges_to_truth(&problem, &mut graph, &options);
}

/// 1 % scale drift per step over 150 poses (the last initial scale is
/// 1.01^149 ≈ 4.4): Sim3 brings every scale back to 1 within 1e-6.
#[test]
fn sim3_corrects_scale_drift() {
    let mut bias = SVector::<f64, 7>::zeros();
    bias[6] = 0.01_f64.ln_1p();
    let (problem, mut graph) = noise_free_loop::<Sim3, 7>(150, bias);
    let worst_initial_scale = graph.nodes().iter().map(|n| n.scale).fold(1.0f64, f64::max);
    assert!(
        worst_initial_scale > 4.0,
        "initial scale drift {worst_initial_scale}"
    );
    assert_converges_to_truth(&problem, &mut graph, &PoseGraphOptions::default());
    for (node, pose) in graph.nodes().iter().enumerate() {
        assert!(
            (pose.scale - 1.0).abs() < 1e-6,
            "node {node}: scale {}",
            pose.scale
        );
    }
}

fn noisy_loop<G: TestGroup<N>, const N: usize>(seed: u64) {
    let nodes = 300;
    let truth = circle_ground_truth(nodes, 1, 10.0);
    let pairs = loop_layout().pairs(nodes);
    let sigmas = G::sigmas(0.002, 0.01, 0.002);
    let corruption = Corruption {
        noise_sigmas: sigmas,
        drift_per_step: drift::<G, N>(0.002, 0.01, 0.002),
    };
    let problem = build_problem::<G, N>(&truth, &pairs, &corruption, &mut Rng::new(seed));
    let information = SMatrix::<f64, N, N>::from_diagonal(&sigmas.map(|s| 1.0 / (s * s)));
    let mut graph = problem_graph(&problem, &[0], &information);
    let before = rms(&pose_errors(graph.nodes(), &problem.ground_truth));
    let summary = graph
        .optimise(&PoseGraphOptions::default())
        .expect("optimises");
    let after = rms(&pose_errors(graph.nodes(), &problem.ground_truth));
    let dof = (N * (pairs.len() - (nodes - 1))) as f64;
    eprintln!(
        "N={N}: chi2 {:.1} -> {:.1} (dof {dof}), rms error {before:.3e} -> {after:.3e}, {} iterations ({:?})",
        summary.initial_chi2, summary.final_chi2, summary.iterations, summary.termination
    );
    assert!((summary.final_chi2 - dof).abs() < 5.0 * (2.0 * dof).sqrt());
    assert!(after * 10.0 < before, "error {before} -> {after}");
}

#[test]
fn se3_noisy_loop_reaches_expected_chi2() {
    noisy_loop::<Se3, 6>(21);
}

#[test]
fn sim3_noisy_loop_reaches_expected_chi2() {
    noisy_loop::<Sim3, 7>(22);
}

#[test]
fn two_thousand_node_multi_lap_graph_converges() {
    let nodes = 2000;
    let truth = circle_ground_truth(nodes, 4, 30.0);
    let layout = EdgeLayout {
        odometry: true,
        covisibility_offsets: vec![2, 3],
        loop_stride: 2,
        laps: 4,
    };
    let pairs = layout.pairs(nodes);
    let sigmas = Se3::sigmas(0.002, 0.01, 0.0);
    let corruption = Corruption {
        noise_sigmas: sigmas,
        drift_per_step: drift::<Se3, 6>(0.0005, 0.005, 0.0),
    };
    let problem = build_problem::<Se3, 6>(&truth, &pairs, &corruption, &mut Rng::new(5));
    let information = SMatrix::<f64, 6, 6>::from_diagonal(&sigmas.map(|s| 1.0 / (s * s)));
    let mut graph = problem_graph(&problem, &[0], &information);
    let before = rms(&pose_errors(graph.nodes(), &problem.ground_truth));
    let summary = graph
        .optimise(&PoseGraphOptions::default())
        .expect("optimises");
    let after = rms(&pose_errors(graph.nodes(), &problem.ground_truth));
    let dof = (6 * (pairs.len() - (nodes - 1))) as f64;
    eprintln!(
        "2000 nodes, {} edges: chi2 {:.1} -> {:.1} (dof {dof}), rms {before:.3e} -> {after:.3e}, {} iterations ({:?}), symbolic {:.1} ms, {:.1} ms/iteration",
        pairs.len(),
        summary.initial_chi2,
        summary.final_chi2,
        summary.iterations,
        summary.termination,
        summary.symbolic_seconds * 1e3,
        summary.mean_iteration_seconds() * 1e3
    );
    assert_eq!(summary.termination, Termination::RelativeDecrease);
    assert!((summary.final_chi2 - dof).abs() < 5.0 * (2.0 * dof).sqrt());
    assert!(after * 10.0 < before);
}

/// Assembly split over threads gives the same run as one thread: final χ²
/// to 1e-9 relative, poses to 1e-9.
#[test]
fn threaded_assembly_matches_single_thread() {
    let nodes = 1000;
    let truth = circle_ground_truth(nodes, 2, 20.0);
    let layout = EdgeLayout {
        odometry: true,
        covisibility_offsets: vec![2, 3],
        loop_stride: 2,
        laps: 2,
    };
    let sigmas = Sim3::sigmas(0.002, 0.01, 0.002);
    let corruption = Corruption {
        noise_sigmas: sigmas,
        drift_per_step: drift::<Sim3, 7>(0.001, 0.005, 0.001),
    };
    let problem =
        build_problem::<Sim3, 7>(&truth, &layout.pairs(nodes), &corruption, &mut Rng::new(4));
    let information = SMatrix::<f64, 7, 7>::from_diagonal(&sigmas.map(|s| 1.0 / (s * s)));
    let mut results = Vec::new();
    for assembly_threads in [1, 3] {
        let mut graph = problem_graph(&problem, &[0], &information);
        let options = PoseGraphOptions {
            assembly_threads,
            ..PoseGraphOptions::default()
        };
        let summary = graph.optimise(&options).expect("optimises");
        results.push((summary.final_chi2, graph.nodes().to_vec()));
    }
    let (single_chi2, single_nodes) = &results[0];
    let (threaded_chi2, threaded_nodes) = &results[1];
    assert!((single_chi2 - threaded_chi2).abs() <= 1e-9 * single_chi2);
    let worst = pose_errors(threaded_nodes, single_nodes)
        .into_iter()
        .fold(0.0, f64::max);
    assert!(worst < 1e-9, "{worst:e}");
}

// --------------------------------------------------------- gauge and fixed

#[test]
fn fixed_nodes_stay_bit_identical() {
    let (problem, _) = noise_free_loop::<Sim3, 7>(120, drift::<Sim3, 7>(0.003, 0.02, 0.003));
    let fixed = [0, 40, 77];
    let mut graph = problem_graph(&problem, &fixed, &SMatrix::identity());
    let before: Vec<Sim3> = graph.nodes().to_vec();
    let summary = graph
        .optimise(&PoseGraphOptions::default())
        .expect("optimises");
    assert_eq!(summary.auto_fixed_node, None);
    assert!(summary.iterations > 0);
    for node in fixed {
        assert_eq!(graph.nodes()[node], before[node], "fixed node {node} moved");
    }
    assert_ne!(graph.nodes()[1], before[1], "free nodes move");
}

#[test]
fn without_fixed_nodes_node_zero_is_held() {
    let (problem, _) = noise_free_loop::<Se3, 6>(100, drift::<Se3, 6>(0.003, 0.02, 0.0));
    let mut graph = problem_graph(&problem, &[], &SMatrix::identity());
    let node_zero = graph.nodes()[0];
    let summary = graph
        .optimise(&PoseGraphOptions::default())
        .expect("optimises");
    assert_eq!(summary.auto_fixed_node, Some(0));
    assert_eq!(summary.free_nodes, 99);
    assert_eq!(graph.nodes()[0], node_zero);
    assert!(!graph.fixed_flags()[0], "the graph's flags are not changed");
    let worst = pose_errors(graph.nodes(), &problem.ground_truth)
        .into_iter()
        .fold(0.0, f64::max);
    assert!(worst < 1e-6, "{worst:e}");
}

#[test]
fn huber_kernel_limits_a_false_loop_closure() {
    let nodes = 120;
    let truth = circle_ground_truth(nodes, 1, 10.0);
    let pairs = loop_layout().pairs(nodes);
    let sigmas = Se3::sigmas(0.002, 0.01, 0.0);
    let corruption = Corruption {
        noise_sigmas: sigmas,
        drift_per_step: drift::<Se3, 6>(0.002, 0.01, 0.0),
    };
    let problem = build_problem::<Se3, 6>(&truth, &pairs, &corruption, &mut Rng::new(3));
    let information = SMatrix::<f64, 6, 6>::from_diagonal(&sigmas.map(|s| 1.0 / (s * s)));
    let mut errors = Vec::new();
    for kernel in [None, Some(RobustKernel::Huber { width: 2.0 })] {
        let mut graph = problem_graph(&problem, &[0], &information);
        // A wrong loop closure: "node 60 is where node 20 is".
        let mut edge = PoseGraphEdge::new(20, 60, Se3::identity()).with_information(information);
        edge.robust_kernel = kernel;
        graph.add_edge(edge).expect("valid edge");
        graph
            .optimise(&PoseGraphOptions::default())
            .expect("optimises");
        errors.push(rms(&pose_errors(graph.nodes(), &problem.ground_truth)));
    }
    eprintln!(
        "rms error without / with Huber: {:.3e} / {:.3e}",
        errors[0], errors[1]
    );
    assert!(errors[1] * 5.0 < errors[0]);
}

// ---------------------------------------------------- dense reference

/// Dense Gauss–Newton with central-difference Jacobians and nalgebra's
/// Cholesky. Returns `(H, b)` at the start and the final χ².
fn dense_reference<G: LieGroup<N>, const N: usize>(
    graph: &PoseGraph<G, N>,
    free: &[usize],
) -> (DMatrix<f64>, DVector<f64>, f64) {
    let residual = |z: &G, from: &G, to: &G| z.compose(from).compose(&to.inverse()).log();
    let column_of = |node: usize| free.iter().position(|&f| f == node);
    let mut nodes = graph.nodes().to_vec();
    let dimension = N * free.len();
    let mut first = None;
    for _ in 0..100 {
        let mut hessian = DMatrix::<f64>::zeros(dimension, dimension);
        let mut gradient = DVector::<f64>::zeros(dimension);
        for edge in graph.edges() {
            let e = residual(&edge.measurement, &nodes[edge.from], &nodes[edge.to]);
            let mut jacobian = DMatrix::<f64>::zeros(N, dimension);
            let h = 1e-6;
            for (end, node) in [(0, edge.from), (1, edge.to)] {
                let Some(block) = column_of(node) else {
                    continue;
                };
                for k in 0..N {
                    let mut delta = SVector::<f64, N>::zeros();
                    delta[k] = h;
                    let mut plus = nodes.clone();
                    let mut minus = nodes.clone();
                    plus[node] = nodes[node].perturb_left(&delta);
                    minus[node] = nodes[node].perturb_left(&(-delta));
                    let _ = end;
                    let derivative =
                        (residual(&edge.measurement, &plus[edge.from], &plus[edge.to])
                            - residual(&edge.measurement, &minus[edge.from], &minus[edge.to]))
                            / (2.0 * h);
                    jacobian
                        .view_mut((0, block * N + k), (N, 1))
                        .copy_from(&derivative);
                }
            }
            let information = DMatrix::from_fn(N, N, |r, c| edge.information[(r, c)]);
            let e = DVector::from_column_slice(e.as_slice());
            hessian += jacobian.transpose() * &information * &jacobian;
            gradient += jacobian.transpose() * &information * e;
        }
        if first.is_none() {
            first = Some((hessian.clone(), gradient.clone()));
        }
        let step = hessian
            .cholesky()
            .expect("positive definite")
            .solve(&(-&gradient));
        for (block, &node) in free.iter().enumerate() {
            let delta = SVector::<f64, N>::from_fn(|k, _| step[block * N + k]);
            nodes[node] = nodes[node].perturb_left(&delta);
        }
        if step.amax() < 1e-12 {
            break;
        }
    }
    let chi2 = graph
        .edges()
        .iter()
        .map(|edge| {
            let e = residual(&edge.measurement, &nodes[edge.from], &nodes[edge.to]);
            e.dot(&(edge.information * e))
        })
        .sum();
    let (hessian, gradient) = first.expect("at least one iteration");
    (hessian, gradient, chi2)
}

fn cross_check<G: TestGroup<N>, const N: usize>() {
    let nodes = 20;
    let truth = circle_ground_truth(nodes, 1, 5.0);
    let mut pairs = loop_layout().pairs(nodes);
    pairs.push((4, 13));
    let sigmas = G::sigmas(0.01, 0.05, 0.01);
    let corruption = Corruption {
        noise_sigmas: sigmas,
        drift_per_step: drift::<G, N>(0.01, 0.05, 0.01),
    };
    let problem = build_problem::<G, N>(&truth, &pairs, &corruption, &mut Rng::new(9));
    // A full (non-diagonal) information matrix: A·Aᵀ + diagonal.
    let mut rng = Rng::new(10);
    let a = SMatrix::<f64, N, N>::from_fn(|_, _| rng.normal());
    let information =
        a * a.transpose() + SMatrix::<f64, N, N>::from_diagonal(&sigmas.map(|s| 1.0 / (s * s)));
    let fixed = [0, 7];
    let mut graph = problem_graph(&problem, &fixed, &information);
    let free: Vec<usize> = (0..nodes).filter(|n| !fixed.contains(n)).collect();
    let (reference_hessian, reference_gradient, reference_chi2) = dense_reference(&graph, &free);

    // One linearisation: assembled H, b vs the numeric reference; sparse vs dense solve.
    let mut solver = PoseGraphSolver::new(&mut graph, PoseGraphOptions::default()).expect("solver");
    solver.linearise();
    let (hessian, gradient) = solver.dense_normal_equations();
    let dimension = solver.dimension();
    let hessian = DMatrix::from_fn(dimension, dimension, |r, c| hessian[r][c]);
    let gradient = DVector::from_vec(gradient);
    // The solver orders its variables for elimination; bring the reference
    // (free nodes in index order) into that order.
    let solver_index = |reference: usize| {
        let block = solver
            .block_of_node(free[reference / N])
            .expect("free node");
        block * N + reference % N
    };
    let mut permuted_hessian = DMatrix::<f64>::zeros(dimension, dimension);
    let mut permuted_gradient = DVector::<f64>::zeros(dimension);
    for r in 0..dimension {
        permuted_gradient[solver_index(r)] = reference_gradient[r];
        for c in 0..dimension {
            permuted_hessian[(solver_index(r), solver_index(c))] = reference_hessian[(r, c)];
        }
    }
    let (reference_hessian, reference_gradient) = (permuted_hessian, permuted_gradient);
    let relative = |a: &DMatrix<f64>, b: &DMatrix<f64>| (a - b).norm() / b.norm();
    assert!(
        relative(&hessian, &reference_hessian) < 1e-6,
        "H: {:e}",
        relative(&hessian, &reference_hessian)
    );
    let gradient_error = (&gradient - &reference_gradient).norm() / reference_gradient.norm();
    assert!(gradient_error < 1e-6, "b: {gradient_error:e}");
    let dense_step = hessian
        .clone()
        .cholesky()
        .expect("positive definite")
        .solve(&(-&gradient));
    let sparse_step = DVector::from_column_slice(solver.solve_step(0.0).expect("solves"));
    let step_error = (&sparse_step - &dense_step).norm() / dense_step.norm();
    assert!(step_error < 1e-9, "step: {step_error:e}");

    let summary = solver.optimise().expect("optimises");
    let chi2_error = (summary.final_chi2 - reference_chi2).abs() / reference_chi2;
    eprintln!(
        "N={N}: chi2 sparse {:.10e} dense {reference_chi2:.10e} (relative {chi2_error:.1e})",
        summary.final_chi2
    );
    assert!(chi2_error < 1e-6);
}

#[test]
fn se3_matches_dense_reference_solver() {
    cross_check::<Se3, 6>();
}

#[test]
fn sim3_matches_dense_reference_solver() {
    cross_check::<Sim3, 7>();
}

// --------------------------------------------------------------- bad input

fn two_nodes() -> PoseGraph<Sim3, 7> {
    let mut graph = PoseGraph::new();
    graph.add_node(Sim3::identity(), true).expect("valid");
    graph
        .add_node(
            Sim3::new(UnitQuaternion::identity(), Vector3::new(1.0, 0.0, 0.0), 1.0),
            false,
        )
        .expect("valid");
    graph
}

#[test]
fn bad_input_gives_typed_errors() {
    let mut graph = two_nodes();
    let z = Sim3::identity();
    assert_eq!(
        graph.add_edge(PoseGraphEdge::new(0, 5, z)),
        Err(OptimError::NodeOutOfRange {
            edge: 0,
            node: 5,
            nodes: 2
        })
    );
    assert_eq!(
        graph.add_edge(PoseGraphEdge::new(1, 1, z)),
        Err(OptimError::SelfLoopEdge { edge: 0, node: 1 })
    );
    let nan = Sim3::new(
        UnitQuaternion::identity(),
        Vector3::new(f64::NAN, 0.0, 0.0),
        1.0,
    );
    assert_eq!(
        graph.add_edge(PoseGraphEdge::new(0, 1, nan)),
        Err(OptimError::InvalidMeasurement { edge: 0 })
    );
    let negative_scale = Sim3::new(UnitQuaternion::identity(), Vector3::zeros(), -1.0);
    assert_eq!(
        graph.add_edge(PoseGraphEdge::new(0, 1, negative_scale)),
        Err(OptimError::InvalidMeasurement { edge: 0 })
    );
    let mut indefinite = SMatrix::<f64, 7, 7>::identity();
    indefinite[(3, 3)] = -1.0;
    let mut asymmetric = SMatrix::<f64, 7, 7>::identity();
    asymmetric[(0, 1)] = 0.5;
    let mut with_nan = SMatrix::<f64, 7, 7>::identity();
    with_nan[(2, 2)] = f64::NAN;
    for information in [indefinite, asymmetric, with_nan, SMatrix::zeros()] {
        assert_eq!(
            graph.add_edge(PoseGraphEdge::new(0, 1, z).with_information(information)),
            Err(OptimError::InformationNotPositiveDefinite { edge: 0 })
        );
    }
    assert_eq!(
        graph.add_edge(
            PoseGraphEdge::new(0, 1, z).with_robust_kernel(RobustKernel::Huber { width: -1.0 })
        ),
        Err(OptimError::InvalidKernelWidth {
            edge: 0,
            width: -1.0
        })
    );
    assert_eq!(
        graph.add_node(nan, false),
        Err(OptimError::InvalidNode { node: 2 })
    );
    assert_eq!(
        graph.set_fixed(9, true),
        Err(OptimError::UnknownNode { node: 9, nodes: 2 })
    );
    assert_eq!(graph.edges().len(), 0, "refused edges are not added");

    graph.add_edge(PoseGraphEdge::new(0, 1, z)).expect("valid");
    let options = PoseGraphOptions {
        relative_chi2_tolerance: f64::NAN,
        ..PoseGraphOptions::default()
    };
    assert!(matches!(
        graph.optimise(&options),
        Err(OptimError::InvalidOption {
            option: "relative_chi2_tolerance",
            ..
        })
    ));
    let no_threads = PoseGraphOptions {
        assembly_threads: 0,
        ..PoseGraphOptions::default()
    };
    assert!(matches!(
        graph.optimise(&no_threads),
        Err(OptimError::InvalidOption {
            option: "assembly_threads",
            ..
        })
    ));
}

#[test]
fn degenerate_graphs_do_not_panic() {
    // Empty graph, all nodes fixed, nodes without edges.
    let mut empty = PoseGraph::<Se3, 6>::new();
    let summary = empty
        .optimise(&PoseGraphOptions::default())
        .expect("nothing to do");
    assert_eq!(summary.termination, Termination::NothingToOptimise);

    let mut all_fixed = PoseGraph::<Se3, 6>::new();
    all_fixed.add_node(Se3::identity(), true).expect("valid");
    all_fixed.add_node(Se3::identity(), true).expect("valid");
    all_fixed
        .add_edge(PoseGraphEdge::new(
            0,
            1,
            Se3::exp(&SVector::from_element(0.1)),
        ))
        .expect("valid");
    let summary = all_fixed
        .optimise(&PoseGraphOptions::default())
        .expect("nothing to do");
    assert_eq!(summary.termination, Termination::NothingToOptimise);
    assert!(summary.final_chi2 > 0.0);

    // A free pair not connected to the fixed node: Gauss–Newton reports the
    // singular system, LM's damping copes.
    let mut split = PoseGraph::<Se3, 6>::new();
    for fixed in [true, false, false, false] {
        split.add_node(Se3::identity(), fixed).expect("valid");
    }
    split
        .add_edge(PoseGraphEdge::new(
            0,
            1,
            Se3::exp(&SVector::from_element(0.1)),
        ))
        .expect("valid");
    split
        .add_edge(PoseGraphEdge::new(
            2,
            3,
            Se3::exp(&SVector::from_element(0.1)),
        ))
        .expect("valid");
    let gauss_newton = PoseGraphOptions {
        algorithm: Algorithm::GaussNewton,
        ..PoseGraphOptions::default()
    };
    assert!(matches!(
        split.clone().optimise(&gauss_newton),
        Err(OptimError::NotPositiveDefinite { iteration: 0, .. })
    ));
    let summary = split
        .optimise(&PoseGraphOptions::default())
        .expect("LM copes");
    assert!(summary.final_chi2 < 1e-12, "{}", summary.final_chi2);
}
