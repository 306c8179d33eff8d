//! The essential graph of a map and its optimisation after a loop
//! correction, as ORB-SLAM3's `Optimizer::OptimizeEssentialGraph` with the
//! scale fixed (stereo, RGB-D), on the faer pose-graph solver.
//!
//! Nodes are every live keyframe's `T_cw`; edges, each measured as
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
use crate::optim::pose_graph::{PoseGraphEdge, PoseGraphOptions, PoseGraphSummary, Se3PoseGraph};
use crate::optim::{LieGroup, Se3};

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
}

/// The graph built from a map, with node ↔ keyframe tables.
#[derive(Debug)]
pub struct EssentialGraph {
    /// The pose graph.
    pub graph: Se3PoseGraph,
    /// Keyframe of each node.
    pub keyframes: Vec<KeyFrameId>,
    /// Edges by kind: loop connections, spanning tree, loop edges, covisibility.
    pub edge_counts: [usize; 4],
}

/// Builds the essential graph (see the module's docs).
pub fn build_essential_graph(
    map: &Map,
    input: &EssentialGraphInput,
) -> Result<EssentialGraph, SlamError> {
    let mut graph = Se3PoseGraph::new();
    let mut node: BTreeMap<KeyFrameId, usize> = BTreeMap::new();
    let mut keyframes = Vec::new();
    for kf in map.keyframes() {
        let fixed = input.fixed == Some(kf.id());
        let n = graph
            .add_node(kf.pose_cw(), fixed)
            .in_stage("essential graph node")?;
        node.insert(kf.id(), n);
        keyframes.push(kf.id());
    }
    let current = |k: KeyFrameId| map.keyframe(k).map(|kf| kf.pose_cw()).ok();
    let before = |k: KeyFrameId| input.uncorrected.get(&k).copied().or_else(|| current(k));
    let mut added: BTreeSet<(KeyFrameId, KeyFrameId)> = BTreeSet::new();
    let mut counts = [0usize; 4];
    let mut add = |graph: &mut Se3PoseGraph,
                   i: KeyFrameId,
                   j: KeyFrameId,
                   ti: Se3,
                   tj: Se3,
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
    /// Each keyframe's pose `T_cw` before the optimisation.
    pub before: BTreeMap<KeyFrameId, Se3>,
    /// Edges in the graph.
    pub edges: usize,
}

/// Optimises the essential graph and writes the poses back.
pub fn optimise_essential_graph(
    map: &mut Map,
    input: &EssentialGraphInput,
) -> Result<EssentialGraphOutcome, SlamError> {
    let mut essential = build_essential_graph(map, input)?;
    let options = PoseGraphOptions {
        max_iterations: 20,
        ..PoseGraphOptions::default()
    };
    let summary = essential
        .graph
        .optimise(&options)
        .in_stage("essential graph")?;
    let mut before = BTreeMap::new();
    for (k, pose) in essential.keyframes.iter().zip(essential.graph.nodes()) {
        if let Ok(kf) = map.keyframe_mut(*k) {
            before.insert(*k, kf.pose_cw());
            kf.set_pose_cw(*pose);
        }
    }
    Ok(EssentialGraphOutcome {
        summary,
        before,
        edges: essential.graph.edges().len(),
    })
}
