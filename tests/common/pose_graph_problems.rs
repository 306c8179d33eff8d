//! Synthetic pose-graph problems with known answers, shared by
//! `tests/optim_pose_graph.rs` and `benches/pose_graph.rs`: a seeded PRNG,
//! circular multi-lap trajectories, odometry / covisibility / loop edges and
//! drifting initial guesses, generic over SE3 and Sim3.
#![allow(dead_code)]

pub use super::rng::Rng;
use nalgebra::{SVector, UnitQuaternion, Vector3};
use spslam::optim::lie::{LieGroup, Se3, Sim3};
use spslam::optim::pose_graph::{PoseGraph, PoseGraphEdge};

/// The groups the tests run on: SE3 (scale fixed) and Sim3.
pub trait TestGroup<const N: usize>: LieGroup<N> + Send + Sync {
    /// A rigid pose as an element of the group (scale 1).
    fn from_rigid(pose: &Se3) -> Self;
    /// The scale (1 for SE3).
    fn scale(&self) -> f64;
    /// Per-component noise sigmas `[ω, υ, (σ)]` from rotation, translation and log-scale sigmas.
    fn sigmas(rotation: f64, translation: f64, log_scale: f64) -> SVector<f64, N>;
}

impl TestGroup<6> for Se3 {
    fn from_rigid(pose: &Se3) -> Self {
        *pose
    }
    fn scale(&self) -> f64 {
        1.0
    }
    fn sigmas(rotation: f64, translation: f64, _log_scale: f64) -> SVector<f64, 6> {
        SVector::<f64, 6>::from_column_slice(&[
            rotation,
            rotation,
            rotation,
            translation,
            translation,
            translation,
        ])
    }
}

impl TestGroup<7> for Sim3 {
    fn from_rigid(pose: &Se3) -> Self {
        Sim3::from_se3(pose)
    }
    fn scale(&self) -> f64 {
        self.scale
    }
    fn sigmas(rotation: f64, translation: f64, log_scale: f64) -> SVector<f64, 7> {
        SVector::<f64, 7>::from_column_slice(&[
            rotation,
            rotation,
            rotation,
            translation,
            translation,
            translation,
            log_scale,
        ])
    }
}

/// World→camera poses of a camera going `laps` times round a circle of
/// radius `radius` (metres), `nodes` poses in all, looking along the track
/// with a small vertical and roll wobble.
pub fn circle_ground_truth(nodes: usize, laps: usize, radius: f64) -> Vec<Se3> {
    let per_lap = (nodes / laps.max(1)).max(1);
    (0..nodes)
        .map(|i| {
            let angle = 2.0 * std::f64::consts::PI * i as f64 / per_lap as f64;
            let position = Vector3::new(
                radius * angle.cos(),
                radius * angle.sin(),
                0.3 * (3.0 * angle).sin() + 0.05 * i as f64 / per_lap as f64,
            );
            let rotation = UnitQuaternion::from_euler_angles(
                0.05 * (2.0 * angle).sin(),
                0.03 * (5.0 * angle).cos(),
                angle + std::f64::consts::FRAC_PI_2,
            );
            // camera→world is (rotation, position); invert to world→camera.
            Se3::new(rotation, position).inverse()
        })
        .collect()
}

/// Which edges a problem has (node pairs `(from, to)`).
#[derive(Debug, Clone, PartialEq)]
pub struct EdgeLayout {
    /// Odometry `i → i+1`.
    pub odometry: bool,
    /// Covisibility `i → i+k` for each `k` listed.
    pub covisibility_offsets: Vec<usize>,
    /// Loop edges to the same place one lap earlier, every `loop_stride` nodes
    /// (0: none); with one lap, edges from the last nodes back to the first.
    pub loop_stride: usize,
    /// Number of laps of the trajectory.
    pub laps: usize,
}

impl EdgeLayout {
    /// The node pairs of this layout over `nodes` nodes.
    pub fn pairs(&self, nodes: usize) -> Vec<(usize, usize)> {
        let mut pairs = Vec::new();
        if self.odometry {
            pairs.extend((0..nodes.saturating_sub(1)).map(|i| (i, i + 1)));
        }
        for &offset in &self.covisibility_offsets {
            pairs.extend((0..nodes.saturating_sub(offset)).map(|i| (i, i + offset)));
        }
        if self.loop_stride > 0 {
            let per_lap = nodes / self.laps.max(1);
            if self.laps <= 1 {
                // Close the loop: the last nodes see the first.
                for k in 0..self.loop_stride.min(nodes / 4) {
                    pairs.push((nodes - 1 - k, k));
                }
            } else {
                pairs.extend(
                    (per_lap..nodes)
                        .step_by(self.loop_stride)
                        .map(|i| (i, i - per_lap)),
                );
            }
        }
        pairs
    }
}

/// A synthetic problem: ground truth, the edges' measurements and a
/// drifting initial guess.
#[derive(Debug, Clone)]
pub struct Problem<G> {
    /// World→camera ground-truth poses.
    pub ground_truth: Vec<G>,
    /// Initial guess: node 0 at ground truth, then odometry with drift.
    pub initial: Vec<G>,
    /// `(from, to, measurement)`.
    pub edges: Vec<(usize, usize, G)>,
}

/// How measurements and the initial guess are corrupted.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Corruption<const N: usize> {
    /// Per-component sigmas of measurement noise `exp(n) · Z` (zeros: exact).
    pub noise_sigmas: SVector<f64, N>,
    /// Drift added to every odometry step of the initial guess: `exp(bias) · Z`.
    pub drift_per_step: SVector<f64, N>,
}

/// Builds a problem on `ground_truth` with `pairs` as edges.
pub fn build_problem<G: TestGroup<N>, const N: usize>(
    ground_truth: &[Se3],
    pairs: &[(usize, usize)],
    corruption: &Corruption<N>,
    rng: &mut Rng,
) -> Problem<G> {
    let ground_truth: Vec<G> = ground_truth.iter().map(G::from_rigid).collect();
    let edges = pairs
        .iter()
        .map(|&(from, to)| {
            let exact = ground_truth[to].compose(&ground_truth[from].inverse());
            let noise = rng.normal_vector(&corruption.noise_sigmas);
            (from, to, G::exp(&noise).compose(&exact))
        })
        .collect();
    let mut initial = Vec::with_capacity(ground_truth.len());
    if let Some(first) = ground_truth.first() {
        initial.push(*first);
    }
    let drift = G::exp(&corruption.drift_per_step);
    for i in 1..ground_truth.len() {
        let step = ground_truth[i].compose(&ground_truth[i - 1].inverse());
        let previous = initial[i - 1];
        initial.push(drift.compose(&step).compose(&previous));
    }
    Problem {
        ground_truth,
        initial,
        edges,
    }
}

/// The pose graph of a problem: initial poses, `fixed` nodes held, every edge
/// with information `information`.
pub fn problem_graph<G: TestGroup<N>, const N: usize>(
    problem: &Problem<G>,
    fixed: &[usize],
    information: &nalgebra::SMatrix<f64, N, N>,
) -> PoseGraph<G, N> {
    let mut graph = PoseGraph::new();
    for (i, pose) in problem.initial.iter().enumerate() {
        graph
            .add_node(*pose, fixed.contains(&i))
            .expect("synthetic poses are valid");
    }
    for &(from, to, measurement) in &problem.edges {
        graph
            .add_edge(PoseGraphEdge::new(from, to, measurement).with_information(*information))
            .expect("synthetic edges are valid");
    }
    graph
}

/// `‖log(estimate · truth⁻¹)‖` for every node.
pub fn pose_errors<G: LieGroup<N>, const N: usize>(estimate: &[G], truth: &[G]) -> Vec<f64> {
    estimate
        .iter()
        .zip(truth)
        .map(|(e, t)| e.compose(&t.inverse()).log().norm())
        .collect()
}

/// Root mean square of a list.
pub fn rms(values: &[f64]) -> f64 {
    (values.iter().map(|v| v * v).sum::<f64>() / values.len().max(1) as f64).sqrt()
}
