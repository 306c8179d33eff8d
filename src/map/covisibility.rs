//! The covisibility graph (keyframes sharing map points) and the spanning
//! tree, as ORB-SLAM3's `UpdateConnections` and `SetBadFlag` maintain them.

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
    /// updates both ends of each edge. The first time a keyframe (other than
    /// the map's first) is connected, its strongest older neighbour becomes
    /// its spanning-tree parent.
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
        let first = self.keyframes.keys().next().copied();
        let node = self.covisibility.entry(keyframe).or_default();
        node.weights = counts;
        node.ordered = kept;
        // Only an older keyframe can become the parent, so the tree has no
        // cycle even when connections are recomputed late.
        let older = node.ordered.iter().find(|(k, _)| *k < keyframe);
        let new_parent = match (node.parent, older) {
            (None, Some((best, _))) if Some(keyframe) != first => Some(*best),
            _ => None,
        };
        if let Some(parent) = new_parent {
            node.parent = Some(parent);
            self.covisibility
                .entry(parent)
                .or_default()
                .children
                .insert(keyframe);
        }
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
    /// an already re-attached keyframe (starting from the removed one's
    /// parent) is attached to it; children left over go to the removed
    /// keyframe's parent. Returns the removed keyframe's parent.
    pub(super) fn detach_from_graph(&mut self, keyframe: KeyFrameId) -> Option<KeyFrameId> {
        let node = self.covisibility.remove(&keyframe)?;
        for other in node.weights.keys() {
            if let Some(n) = self.covisibility.get_mut(other) {
                n.disconnect(keyframe);
            }
        }
        let parent = node.parent;
        if let Some(p) = parent.and_then(|p| self.covisibility.get_mut(&p)) {
            p.children.remove(&keyframe);
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

    fn set_parent(&mut self, child: KeyFrameId, parent: KeyFrameId) {
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
