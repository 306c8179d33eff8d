//! The essential graph of a map and its optimisation after a loop
//! correction, as ORB-SLAM3's `Optimizer::OptimizeEssentialGraph`: in
//! SE(3) with the scale fixed (stereo, RGB-D), in Sim(3) for a monocular
//! map (its scale drifts), on the faer pose-graph solver.
//!
//! Nodes are every live keyframe's `T_cw` (monocular: the corrected
//! keyframes' Sim(3) poses, scale 1 elsewhere, as ORB-SLAM3's
//! `CorrectedSim3` / `NonCorrectedSim3`); edges, each measured as
//! `Z_ij = T_j·T_i⁻¹` with identity information and no robust kernel:
//! - the new loop connections, from the corrected poses (weak ones, under
//!   [`MIN_ESSENTIAL_WEIGHT`] shared points, are skipped except the main
//!   query–loop edge);
//! - the spanning tree, earlier loop edges and covisibility edges of weight
//!   at least [`MIN_ESSENTIAL_WEIGHT`], from the poses before the
//!   correction, so the graph keeps the odometry and spreads the loop's
//!   error along it.
//!
//! The loop keyframe is held fixed.

use std::collections::{BTreeMap, BTreeSet};

use crate::error::{MapContext, SlamError};
use crate::map::{KeyFrameId, Map};
use crate::optim::pose_graph::{PoseGraph, PoseGraphEdge, PoseGraphOptions, PoseGraphSummary};
use crate::optim::{LieGroup, Se3, Sim3};

/// Covisibility weight of an essential-graph edge (ORB-SLAM3: 100).
pub const MIN_ESSENTIAL_WEIGHT: usize = 100;

/// What the optimisation needs besides the map.
#[derive(Debug, Clone, Default)]
pub struct EssentialGraphInput {
    /// Poses `T_cw` before the correction of the keyframes it moved.
    pub uncorrected: BTreeMap<KeyFrameId, Se3>,
    /// New connections the loop made, per keyframe of the corrected side.
    pub loop_connections: BTreeMap<KeyFrameId, BTreeSet<KeyFrameId>>,
    /// The query keyframe.
    pub query: Option<KeyFrameId>,
    /// The loop keyframe, held fixed.
    pub fixed: Option<KeyFrameId>,
    /// Monocular maps: the corrected keyframes' Sim(3) poses `S_cw` (their
    /// scale: the query side's over the loop side's). With it the graph is
    /// Sim(3); without it, SE(3).
    pub corrected_sim3: Option<BTreeMap<KeyFrameId, Sim3>>,
}

/// A node pose type of the essential graph: SE(3) or Sim(3).
pub trait GraphPose<const N: usize>: LieGroup<N> + Copy + Send + Sync {
    /// The keyframe pose `T_cw` as a node (scale 1).
    fn from_pose(pose: &Se3) -> Self;
    /// A corrected similarity as a node; `None` where the graph has no
    /// scale (SE(3)).
    fn from_similarity(similarity: &Sim3) -> Option<Self>;
}

impl GraphPose<6> for Se3 {
    fn from_pose(pose: &Se3) -> Self {
        *pose
    }

    fn from_similarity(_: &Sim3) -> Option<Self> {
        None
    }
}

impl GraphPose<7> for Sim3 {
    fn from_pose(pose: &Se3) -> Self {
        Sim3::from_se3(pose)
    }

    fn from_similarity(similarity: &Sim3) -> Option<Self> {
        Some(*similarity)
    }
}

/// The graph built from a map, with node ↔ keyframe tables.
#[derive(Debug)]
pub struct EssentialGraph<G, const N: usize> {
    /// The pose graph.
    pub graph: PoseGraph<G, N>,
    /// Keyframe of each node.
    pub keyframes: Vec<KeyFrameId>,
    /// Edges by kind: loop connections, spanning tree, loop edges, covisibility.
    pub edge_counts: [usize; 4],
}

/// Builds the essential graph (see the module's docs) over `G`: SE(3)
/// ([`Se3`], 6) or Sim(3) ([`Sim3`], 7, with `input.corrected_sim3`).
pub fn build_essential_graph<G: GraphPose<N>, const N: usize>(
    map: &Map,
    input: &EssentialGraphInput,
) -> Result<EssentialGraph<G, N>, SlamError> {
    let corrected = |k: KeyFrameId| -> Option<G> {
        G::from_similarity(input.corrected_sim3.as_ref()?.get(&k)?)
    };
    let current = |k: KeyFrameId| -> Option<G> {
        corrected(k).or_else(|| map.keyframe(k).map(|kf| G::from_pose(&kf.pose_cw())).ok())
    };
    let before = |k: KeyFrameId| -> Option<G> {
        input
            .uncorrected
            .get(&k)
            .map(G::from_pose)
            .or_else(|| current(k))
    };
    let mut graph = PoseGraph::<G, N>::new();
    let mut node: BTreeMap<KeyFrameId, usize> = BTreeMap::new();
    let mut keyframes = Vec::new();
    for kf in map.keyframes() {
        let fixed = input.fixed == Some(kf.id());
        let Some(pose) = current(kf.id()) else {
            continue;
        };
        let n = graph
            .add_node(pose, fixed)
            .in_stage("essential graph node")?;
        node.insert(kf.id(), n);
        keyframes.push(kf.id());
    }
    let mut added: BTreeSet<(KeyFrameId, KeyFrameId)> = BTreeSet::new();
    let mut counts = [0usize; 4];
    let mut add = |graph: &mut PoseGraph<G, N>,
                   i: KeyFrameId,
                   j: KeyFrameId,
                   ti: G,
                   tj: G,
                   kind: usize|
     -> Result<(), SlamError> {
        let key = (i.min(j), i.max(j));
        let (Some(&ni), Some(&nj)) = (node.get(&i), node.get(&j)) else {
            return Ok(());
        };
        if i == j || !added.insert(key) {
            return Ok(());
        }
        let measurement = tj.compose(&ti.inverse());
        graph
            .add_edge(PoseGraphEdge::new(ni, nj, measurement))
            .in_stage("essential graph edge")?;
        counts[kind] += 1;
        Ok(())
    };
    for (i, connections) in &input.loop_connections {
        for j in connections {
            let main = input.query == Some(*i) && input.fixed == Some(*j);
            if !main && map.covisibility_weight(*i, *j) < MIN_ESSENTIAL_WEIGHT {
                continue;
            }
            if let (Some(ti), Some(tj)) = (current(*i), current(*j)) {
                add(&mut graph, *i, *j, ti, tj, 0)?;
            }
        }
    }
    for kf in map.keyframes() {
        let i = kf.id();
        let Some(ti) = before(i) else { continue };
        let mut neighbours: Vec<(KeyFrameId, usize)> = Vec::new();
        if let Some(parent) = map.parent(i) {
            neighbours.push((parent, 1));
        }
        neighbours.extend(map.loop_edges(i).into_iter().map(|k| (k, 2)));
        neighbours.extend(
            map.covisible_with_weight(i, MIN_ESSENTIAL_WEIGHT)
                .into_iter()
                .map(|k| (k, 3)),
        );
        for (j, kind) in neighbours {
            if let Some(tj) = before(j) {
                add(&mut graph, i, j, ti, tj, kind)?;
            }
        }
    }
    Ok(EssentialGraph {
        graph,
        keyframes,
        edge_counts: counts,
    })
}

/// What an essential-graph optimisation did.
#[derive(Debug)]
pub struct EssentialGraphOutcome {
    /// The solver's summary.
    pub summary: PoseGraphSummary,
    /// Each keyframe's node before the optimisation, as a similarity
    /// (scale 1 in SE(3)): a point `X` it references sits at
    /// `before·X` in its camera, in the node's scale.
    pub before: BTreeMap<KeyFrameId, Sim3>,
    /// Each keyframe's scale after the optimisation (1 in SE(3)).
    pub scale_after: BTreeMap<KeyFrameId, f64>,
    /// Edges in the graph.
    pub edges: usize,
}

/// Optimises the essential graph (Sim(3) when `input.corrected_sim3` is
/// given, else SE(3)) and writes the poses back: a Sim(3) node `(s, R, t)`
/// becomes the keyframe pose `(R, t/s)` (ORB-SLAM3's conversion).
pub fn optimise_essential_graph(
    map: &mut Map,
    input: &EssentialGraphInput,
) -> Result<EssentialGraphOutcome, SlamError> {
    if input.corrected_sim3.is_some() {
        optimise_as::<Sim3, 7>(map, input, |s| (*s, s.to_se3_unscaled()))
    } else {
        optimise_as::<Se3, 6>(map, input, |t| (Sim3::from_se3(t), *t))
    }
}

fn optimise_as<G: GraphPose<N>, const N: usize>(
    map: &mut Map,
    input: &EssentialGraphInput,
    split: impl Fn(&G) -> (Sim3, Se3),
) -> Result<EssentialGraphOutcome, SlamError> {
    let mut essential = build_essential_graph::<G, N>(map, input)?;
    let initial: Vec<G> = essential.graph.nodes().to_vec();
    let options = PoseGraphOptions {
        max_iterations: 20,
        ..PoseGraphOptions::default()
    };
    let summary = essential
        .graph
        .optimise(&options)
        .in_stage("essential graph")?;
    let mut before = BTreeMap::new();
    let mut scale_after = BTreeMap::new();
    for ((k, node), start) in essential
        .keyframes
        .iter()
        .zip(essential.graph.nodes())
        .zip(&initial)
    {
        if let Ok(kf) = map.keyframe_mut(*k) {
            let (after, pose) = split(node);
            before.insert(*k, split(start).0);
            scale_after.insert(*k, after.scale);
            kf.set_pose_cw(pose);
        }
    }
    Ok(EssentialGraphOutcome {
        summary,
        before,
        scale_after,
        edges: essential.graph.edges().len(),
    })
}
