//! The covisibility graph (keyframes sharing map points) and the spanning
//! tree, as ORB-SLAM3's `UpdateConnections` and `SetBadFlag` maintain them.
//!
//! The spanning tree is rooted at the map's first keyframe, which
//! [`Map::erase_keyframe`] never removes. A keyframe joins the tree the first
//! time [`Map::update_connections`] runs on it (ORB-SLAM3 adds a keyframe to
//! the map only after its first `UpdateConnections`; here tracking connects
//! it right after adding it and its observations). Until then it is
//! *unconnected*: it has no parent, no keyframe takes it as parent, and it
//! has no children. From then on it always has a live parent:
//! - on its first connection its parent becomes its most covisible keyframe
//!   already in the tree; a keyframe sharing no point with any keyframe in
//!   the tree is attached to the newest older keyframe in the tree (see
//!   [`Map::update_connections`] for why);
//! - removing a keyframe re-attaches its children inside the removed
//!   keyframe's subtree or to its parent, as `SetBadFlag` does.
//!
//! A keyframe only ever attaches to a keyframe already in the tree, and only
//! when it has no descendants (first connection) or to keyframes outside its
//! own subtree (re-attachment), so the tree never gets a cycle.

use std::collections::{BTreeMap, BTreeSet};

use super::ids::KeyFrameId;
use super::Map;

/// Keyframes sharing at least this many points are connected (ORB-SLAM3: 15).
pub const COVISIBILITY_THRESHOLD: usize = 15;

/// One keyframe's edges.
#[derive(Debug, Clone, Default)]
pub(super) struct CovisibilityNode {
    /// Shared-point count with every keyframe it shares a point with.
    pub(super) weights: BTreeMap<KeyFrameId, usize>,
    /// Connected keyframes, by decreasing weight then id.
    pub(super) ordered: Vec<(KeyFrameId, usize)>,
    /// Spanning-tree parent.
    pub(super) parent: Option<KeyFrameId>,
    /// Spanning-tree children.
    pub(super) children: BTreeSet<KeyFrameId>,
    /// Whether [`Map::update_connections`] has run on it (ORB-SLAM3's
    /// `!mbFirstConnection`): it is in the spanning tree.
    pub(super) connected: bool,
    /// Keyframes it was joined to by a closed loop (ORB-SLAM3's
    /// `mspLoopEdges`), kept for the essential graph.
    pub(super) loop_edges: BTreeSet<KeyFrameId>,
}

impl CovisibilityNode {
    fn connect(&mut self, other: KeyFrameId, weight: usize) {
        self.weights.insert(other, weight);
        self.ordered.retain(|(id, _)| *id != other);
        self.ordered.push((other, weight));
        sort_by_weight(&mut self.ordered);
    }

    fn disconnect(&mut self, other: KeyFrameId) {
        self.weights.remove(&other);
        self.ordered.retain(|(id, _)| *id != other);
    }
}

fn sort_by_weight(list: &mut [(KeyFrameId, usize)]) {
    list.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
}

impl Map {
    /// Recounts the points `keyframe` shares with every other keyframe and
    /// updates both ends of each edge.
    ///
    /// The first time it runs on a keyframe other than the map's first (the
    /// root), the keyframe joins the spanning tree, as in ORB-SLAM3's
    /// `UpdateConnections`: its parent becomes its most covisible keyframe
    /// (most shared points, then lowest id) among those already in the tree.
    /// ORB-SLAM3 takes the first of its ordered connections, which are all
    /// in the tree there; keyframes not connected yet are skipped here, so
    /// a keyframe never becomes the parent of one of its ancestors. Later
    /// calls leave the parent alone (it only changes when the parent is
    /// removed), so recomputing connections late cannot create a cycle.
    ///
    /// A keyframe sharing no point with any keyframe in the tree is attached
    /// to the newest older keyframe in the tree (the root at worst), not to
    /// the root: the newest older keyframe is the one tracking came from, so
    /// it is the best guess at a spatial neighbour. The root would gather
    /// unrelated children (which tracking pulls into its local map as the
    /// root's family) and long, meaningless relative poses for culled
    /// keyframes.
    pub fn update_connections(&mut self, keyframe: KeyFrameId) {
        let Some(kf) = self.keyframes.get(&keyframe) else {
            return;
        };
        let mut counts: BTreeMap<KeyFrameId, usize> = BTreeMap::new();
        for (_, point) in kf.observed_points() {
            if let Some(p) = self.points.get(&point) {
                for other in p.observations.keys().filter(|k| **k != keyframe) {
                    *counts.entry(*other).or_default() += 1;
                }
            }
        }
        let mut kept: Vec<(KeyFrameId, usize)> = counts
            .iter()
            .filter(|(_, w)| **w >= COVISIBILITY_THRESHOLD)
            .map(|(k, w)| (*k, *w))
            .collect();
        if kept.is_empty() {
            // Keep the strongest one so no keyframe is left unconnected.
            if let Some((k, w)) = counts.iter().max_by(|a, b| a.1.cmp(b.1).then(b.0.cmp(a.0))) {
                kept.push((*k, *w));
            }
        }
        for (other, weight) in &kept {
            self.covisibility
                .entry(*other)
                .or_default()
                .connect(keyframe, *weight);
        }
        sort_by_weight(&mut kept);
        let first_connection = !self
            .covisibility
            .get(&keyframe)
            .is_some_and(|node| node.connected);
        let new_parent = if first_connection && !self.is_root(keyframe) {
            self.first_parent(keyframe, &counts)
        } else {
            None
        };
        let node = self.covisibility.entry(keyframe).or_default();
        node.weights = counts;
        node.ordered = kept;
        node.connected = true;
        if let Some(parent) = new_parent {
            self.set_parent(keyframe, parent);
        }
    }

    /// The parent `keyframe` gets on its first connection: the keyframe in
    /// the tree sharing most points with it (then the lowest id), or the
    /// newest older keyframe in the tree when it shares none with one.
    fn first_parent(
        &self,
        keyframe: KeyFrameId,
        counts: &BTreeMap<KeyFrameId, usize>,
    ) -> Option<KeyFrameId> {
        counts
            .iter()
            .filter(|(k, _)| **k != keyframe && self.in_tree(**k))
            .max_by(|a, b| a.1.cmp(b.1).then(b.0.cmp(a.0)))
            .map(|(k, _)| *k)
            .or_else(|| self.newest_older_in_tree(keyframe))
    }

    /// The newest live keyframe older than `keyframe` in the spanning tree
    /// (the root at worst; `None` only for the root itself).
    fn newest_older_in_tree(&self, keyframe: KeyFrameId) -> Option<KeyFrameId> {
        self.keyframes
            .range(..keyframe)
            .rev()
            .map(|(k, _)| *k)
            .find(|k| self.in_tree(*k))
    }

    /// The map's first live keyframe, the spanning tree's root.
    fn is_root(&self, keyframe: KeyFrameId) -> bool {
        self.keyframes.keys().next() == Some(&keyframe)
    }

    /// Whether a live keyframe is in the spanning tree: the root, or
    /// connected at least once.
    fn in_tree(&self, keyframe: KeyFrameId) -> bool {
        self.is_root(keyframe)
            || self
                .covisibility
                .get(&keyframe)
                .is_some_and(|node| node.connected)
    }

    /// The `n` keyframes sharing most points with `keyframe` (all when `n` is
    /// `usize::MAX`), strongest first.
    pub fn best_covisible(&self, keyframe: KeyFrameId, n: usize) -> Vec<KeyFrameId> {
        self.covisibility
            .get(&keyframe)
            .map(|node| node.ordered.iter().take(n).map(|(k, _)| *k).collect())
            .unwrap_or_default()
    }

    /// Connected keyframes with at least `min_weight` shared points.
    pub fn covisible_with_weight(
        &self,
        keyframe: KeyFrameId,
        min_weight: usize,
    ) -> Vec<KeyFrameId> {
        self.covisibility
            .get(&keyframe)
            .map(|node| {
                node.ordered
                    .iter()
                    .take_while(|(_, w)| *w >= min_weight)
                    .map(|(k, _)| *k)
                    .collect()
            })
            .unwrap_or_default()
    }

    /// Number of points `a` shares with `b` (0 when unconnected).
    pub fn covisibility_weight(&self, a: KeyFrameId, b: KeyFrameId) -> usize {
        self.covisibility
            .get(&a)
            .and_then(|node| node.weights.get(&b).copied())
            .unwrap_or(0)
    }

    /// Joins two keyframes by a loop edge (both directions; ORB-SLAM3's
    /// `AddLoopEdge`), for the essential graph of later corrections.
    pub fn add_loop_edge(&mut self, a: KeyFrameId, b: KeyFrameId) {
        if a == b || !self.keyframes.contains_key(&a) || !self.keyframes.contains_key(&b) {
            return;
        }
        self.covisibility.entry(a).or_default().loop_edges.insert(b);
        self.covisibility.entry(b).or_default().loop_edges.insert(a);
    }

    /// The keyframes joined to `keyframe` by loop edges, in id order.
    pub fn loop_edges(&self, keyframe: KeyFrameId) -> Vec<KeyFrameId> {
        self.covisibility
            .get(&keyframe)
            .map(|n| n.loop_edges.iter().copied().collect())
            .unwrap_or_default()
    }

    /// The spanning-tree parent.
    pub fn parent(&self, keyframe: KeyFrameId) -> Option<KeyFrameId> {
        self.covisibility.get(&keyframe).and_then(|n| n.parent)
    }

    /// The spanning-tree children, in id order.
    pub fn children(&self, keyframe: KeyFrameId) -> Vec<KeyFrameId> {
        self.covisibility
            .get(&keyframe)
            .map(|n| n.children.iter().copied().collect())
            .unwrap_or_default()
    }

    /// Removes a keyframe from the graph and gives its children new parents,
    /// as ORB-SLAM3's `SetBadFlag`: repeatedly, the child most covisible with
    /// a candidate (the removed keyframe's parent, then the children already
    /// re-attached) is attached to it; children connected to no candidate
    /// go to the removed keyframe's parent. Returns the keyframe
    /// its pose is to be kept relative to: its parent, or, for a keyframe
    /// never connected (so without parent or children), the newest older
    /// keyframe in the tree, where a first connection without covisible
    /// keyframes would have attached it. `None` only for the root (which
    /// [`Map::erase_keyframe`] never removes) or a keyframe that is not live.
    pub(super) fn detach_from_graph(&mut self, keyframe: KeyFrameId) -> Option<KeyFrameId> {
        let node = self.covisibility.remove(&keyframe)?;
        for other in node.weights.keys() {
            if let Some(n) = self.covisibility.get_mut(other) {
                n.disconnect(keyframe);
            }
        }
        if let Some(p) = node.parent.and_then(|p| self.covisibility.get_mut(&p)) {
            p.children.remove(&keyframe);
        }
        let parent = node.parent.or_else(|| self.newest_older_in_tree(keyframe));
        // Loop edges survive the keyframe: they move to its parent.
        for other in &node.loop_edges {
            if let Some(n) = self.covisibility.get_mut(other) {
                n.loop_edges.remove(&keyframe);
            }
        }
        if let Some(p) = parent {
            for other in node.loop_edges.iter().filter(|o| **o != p) {
                self.covisibility
                    .entry(p)
                    .or_default()
                    .loop_edges
                    .insert(*other);
                self.covisibility
                    .entry(*other)
                    .or_default()
                    .loop_edges
                    .insert(p);
            }
        }
        let mut orphans: BTreeSet<KeyFrameId> = node.children;
        let mut candidates: BTreeSet<KeyFrameId> = parent.into_iter().collect();
        while !orphans.is_empty() {
            let mut best: Option<(usize, KeyFrameId, KeyFrameId)> = None;
            for child in &orphans {
                let Some(child_node) = self.covisibility.get(child) else {
                    continue;
                };
                for (other, weight) in &child_node.ordered {
                    if candidates.contains(other) && best.is_none_or(|(w, _, _)| *weight > w) {
                        best = Some((*weight, *child, *other));
                    }
                }
            }
            let Some((_, child, new_parent)) = best else {
                break;
            };
            self.set_parent(child, new_parent);
            orphans.remove(&child);
            candidates.insert(child);
        }
        for child in orphans {
            match parent {
                Some(p) => self.set_parent(child, p),
                None => {
                    if let Some(n) = self.covisibility.get_mut(&child) {
                        n.parent = None;
                    }
                }
            }
        }
        parent
    }

    pub(super) fn set_parent(&mut self, child: KeyFrameId, parent: KeyFrameId) {
        if let Some(n) = self.covisibility.get_mut(&child) {
            n.parent = Some(parent);
        }
        self.covisibility
            .entry(parent)
            .or_default()
            .children
            .insert(child);
    }
}
