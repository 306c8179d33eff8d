//! A full consistency check of the map's bookkeeping, for tests and debug
//! assertions: both sides of every association, observation weights, the
//! covisibility nodes and the spanning tree, culled keyframes and fused points.

use std::collections::BTreeSet;

use super::ids::{KeyFrameId, MapPointId};
use super::{observation_weight, Map};

/// The first inconsistency [`Map::check_invariants`] found.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InvariantViolation {
    /// Stored parts whose id base lies above the id counters.
    #[error("the id base {base} lies above the next ids ({next_keyframe}, {next_point})")]
    IdBaseAboveCounters {
        /// The first id the map issues.
        base: u64,
        /// The next keyframe id.
        next_keyframe: u64,
        /// The next point id.
        next_point: u64,
    },
    /// Stored parts holding a keyframe twice.
    #[error("{keyframe} is stored twice")]
    DuplicateKeyFrame {
        /// The keyframe.
        keyframe: KeyFrameId,
    },
    /// Stored parts holding a point twice.
    #[error("{point} is stored twice")]
    DuplicateMapPoint {
        /// The point.
        point: MapPointId,
    },
    /// A keyframe whose per-level tables disagree in length.
    #[error("{keyframe} has per-level tables of different lengths")]
    ScaleTablesMismatch {
        /// The keyframe.
        keyframe: KeyFrameId,
    },
    /// A keypoint on a pyramid level the keyframe's tables do not have.
    #[error(
        "{keyframe} keypoint {index} is on level {octave}, but the keyframe has {levels} levels"
    )]
    OctaveOutOfRange {
        /// The keyframe.
        keyframe: KeyFrameId,
        /// The keypoint.
        index: usize,
        /// Its level.
        octave: i32,
        /// Levels in the tables.
        levels: usize,
    },
    /// A keyframe is stored under another id than its own.
    #[error("the keyframe stored under {key} says it is {stored}")]
    KeyFrameIdMismatch {
        /// The id it is stored under.
        key: KeyFrameId,
        /// The id it reports.
        stored: KeyFrameId,
    },
    /// A keyframe id the map has not handed out yet.
    #[error("{keyframe} was never issued (next keyframe id is {next})")]
    UnissuedKeyFrameId {
        /// The keyframe.
        keyframe: KeyFrameId,
        /// The next id the map would issue.
        next: u64,
    },
    /// A keyframe whose keypoints, descriptors and stereo entries disagree in number.
    #[error("{keyframe} has {keypoints} keypoints, {descriptors} descriptors and {stereo} stereo entries")]
    MeasurementsMismatch {
        /// The keyframe.
        keyframe: KeyFrameId,
        /// Keypoints.
        keypoints: usize,
        /// Descriptor rows.
        descriptors: usize,
        /// Stereo entries.
        stereo: usize,
    },
    /// A keyframe with a map-point slot count other than its keypoint count.
    #[error("{keyframe} has {slots} map-point slots for {keypoints} keypoints")]
    SlotCountMismatch {
        /// The keyframe.
        keyframe: KeyFrameId,
        /// Map-point slots.
        slots: usize,
        /// Keypoints.
        keypoints: usize,
    },
    /// A keyframe pose with a NaN or infinite entry.
    #[error("{keyframe} has a non-finite pose")]
    NonFinitePose {
        /// The keyframe.
        keyframe: KeyFrameId,
    },
    /// A keyframe slot refers to a point that is not live.
    #[error("{keyframe} keypoint {index} refers to {point}, which is not live")]
    SlotWithoutPoint {
        /// The keyframe.
        keyframe: KeyFrameId,
        /// The keypoint index.
        index: usize,
        /// The point it refers to.
        point: MapPointId,
    },
    /// A keyframe slot refers to a live point that does not record that
    /// observation (or records it at another keypoint).
    #[error(
        "{keyframe} keypoint {index} refers to {point}, whose observation of it is at {observed:?}"
    )]
    SlotWithoutObservation {
        /// The keyframe.
        keyframe: KeyFrameId,
        /// The keypoint index.
        index: usize,
        /// The point it refers to.
        point: MapPointId,
        /// The keypoint index the point records for this keyframe, if any.
        observed: Option<usize>,
    },
    /// A map point is stored under another id than its own.
    #[error("the map point stored under {key} says it is {stored}")]
    MapPointIdMismatch {
        /// The id it is stored under.
        key: MapPointId,
        /// The id it reports.
        stored: MapPointId,
    },
    /// A map point id the map has not handed out yet.
    #[error("{point} was never issued (next map point id is {next})")]
    UnissuedMapPointId {
        /// The point.
        point: MapPointId,
        /// The next id the map would issue.
        next: u64,
    },
    /// A map point position with a NaN or infinite coordinate.
    #[error("{point} has a non-finite position")]
    NonFinitePosition {
        /// The point.
        point: MapPointId,
    },
    /// A point records an observation by a keyframe that is not live.
    #[error("{point} records an observation by {keyframe} (keypoint {index}), which is not live")]
    ObservationWithoutKeyFrame {
        /// The point.
        point: MapPointId,
        /// The observing keyframe.
        keyframe: KeyFrameId,
        /// The keypoint index recorded.
        index: usize,
    },
    /// A point records an observation whose keyframe slot holds something else.
    #[error("{point} records {keyframe} keypoint {index}, whose slot holds {slot:?}")]
    ObservationWithoutSlot {
        /// The point.
        point: MapPointId,
        /// The observing keyframe.
        keyframe: KeyFrameId,
        /// The keypoint index recorded.
        index: usize,
        /// What the slot holds (`None`: nothing, or the index is out of range).
        slot: Option<MapPointId>,
    },
    /// A point's weighted observation count is not the sum of its
    /// observations' weights (2 with a stereo measurement, 1 without).
    #[error("{point} counts {stored} weighted observations; its observations weigh {expected}")]
    WeightedObservationsMismatch {
        /// The point.
        point: MapPointId,
        /// The count it stores.
        stored: usize,
        /// The sum of its observations' weights.
        expected: usize,
    },
    /// An observed point whose reference keyframe neither observes it nor created it.
    #[error("{point} has reference {reference}, which neither observes nor created it")]
    ReferenceNotObserver {
        /// The point.
        point: MapPointId,
        /// Its reference keyframe.
        reference: KeyFrameId,
    },
    /// A live keyframe without a covisibility node.
    #[error("{keyframe} has no covisibility node")]
    MissingCovisibilityNode {
        /// The keyframe.
        keyframe: KeyFrameId,
    },
    /// A covisibility node for a keyframe that is not live.
    #[error("there is a covisibility node for {keyframe}, which is not live")]
    CovisibilityNodeWithoutKeyFrame {
        /// The node's keyframe.
        keyframe: KeyFrameId,
    },
    /// A keyframe connected to itself.
    #[error("{keyframe} has a covisibility edge to itself")]
    CovisibilitySelfEdge {
        /// The keyframe.
        keyframe: KeyFrameId,
    },
    /// A covisibility edge sharing no point.
    #[error("{keyframe} has a covisibility edge of weight 0 to {other}")]
    ZeroWeightEdge {
        /// The keyframe.
        keyframe: KeyFrameId,
        /// The other end.
        other: KeyFrameId,
    },
    /// A connected keyframe whose weight in the ordered list differs from
    /// the node's weight map (or is missing from it).
    #[error("{keyframe} lists {other} with weight {listed} but its weight map has {weight:?}")]
    ConnectionWeightMismatch {
        /// The keyframe.
        keyframe: KeyFrameId,
        /// The connected keyframe.
        other: KeyFrameId,
        /// The weight in the ordered list.
        listed: usize,
        /// The weight in the weight map.
        weight: Option<usize>,
    },
    /// Connected keyframes not in (decreasing weight, increasing id) order,
    /// or listed twice.
    #[error("{keyframe} lists {first} before {second}, against (weight, id) order")]
    UnsortedConnections {
        /// The keyframe.
        keyframe: KeyFrameId,
        /// The entry listed first.
        first: KeyFrameId,
        /// The entry listed next.
        second: KeyFrameId,
    },
    /// The map's first keyframe (the spanning tree's root) has a parent.
    #[error("the root {root} has the parent {parent}")]
    RootHasParent {
        /// The root.
        root: KeyFrameId,
        /// Its parent.
        parent: KeyFrameId,
    },
    /// A spanning-tree parent that is not live.
    #[error("{keyframe} has the parent {parent}, which is not live")]
    ParentNotLive {
        /// The keyframe.
        keyframe: KeyFrameId,
        /// Its parent.
        parent: KeyFrameId,
    },
    /// A spanning-tree parent that does not list the keyframe as a child.
    #[error("{keyframe} has the parent {parent}, which does not list it as a child")]
    ParentWithoutChild {
        /// The keyframe.
        keyframe: KeyFrameId,
        /// Its parent.
        parent: KeyFrameId,
    },
    /// A spanning-tree child that is not live.
    #[error("{keyframe} has the child {child}, which is not live")]
    ChildNotLive {
        /// The keyframe.
        keyframe: KeyFrameId,
        /// The child.
        child: KeyFrameId,
    },
    /// A spanning-tree child whose parent is another keyframe (or none).
    #[error("{keyframe} has the child {child}, whose parent is {parent:?}")]
    ChildWithOtherParent {
        /// The keyframe.
        keyframe: KeyFrameId,
        /// The child.
        child: KeyFrameId,
        /// The child's parent.
        parent: Option<KeyFrameId>,
    },
    /// A keyframe other than the root, connected at least once, without a
    /// spanning-tree parent.
    #[error("{keyframe} is connected but has no spanning-tree parent")]
    MissingParent {
        /// The keyframe.
        keyframe: KeyFrameId,
    },
    /// A keyframe never connected (not in the spanning tree) with a parent.
    #[error("{keyframe} was never connected but has the parent {parent}")]
    UnconnectedWithParent {
        /// The keyframe.
        keyframe: KeyFrameId,
        /// Its parent.
        parent: KeyFrameId,
    },
    /// A keyframe other than the root, never connected (not in the
    /// spanning tree), with a child.
    #[error("{keyframe} was never connected but has the child {child}")]
    UnconnectedWithChild {
        /// The keyframe.
        keyframe: KeyFrameId,
        /// The child.
        child: KeyFrameId,
    },
    /// Walking up the spanning tree from a keyframe never reaches the root.
    #[error("the spanning-tree parents of {keyframe} loop")]
    SpanningTreeCycle {
        /// The keyframe the walk started from.
        keyframe: KeyFrameId,
    },
    /// A keyframe id the map issued that is neither live nor culled, so
    /// [`Map::pose_cw_of`] fails for it.
    #[error("{keyframe} was issued but is neither live nor recorded as culled")]
    KeyFrameLost {
        /// The keyframe.
        keyframe: KeyFrameId,
    },
    /// A keyframe recorded as culled is still live.
    #[error("{keyframe} is recorded as culled but is live")]
    CulledKeyFrameLive {
        /// The keyframe.
        keyframe: KeyFrameId,
    },
    /// A culled keyframe's chain of culled parents loops.
    #[error("the parent chain of culled {keyframe} loops")]
    CulledChainLoop {
        /// The culled keyframe.
        keyframe: KeyFrameId,
    },
    /// A culled keyframe's chain of culled parents ends at a keyframe that
    /// is neither live nor culled, so [`Map::pose_cw_of`] fails for it.
    #[error("the parent chain of culled {keyframe} ends at {missing}, which is not live")]
    CulledChainBroken {
        /// The culled keyframe.
        keyframe: KeyFrameId,
        /// Where the chain ends.
        missing: KeyFrameId,
    },
    /// A point recorded as fused into another is still live.
    #[error("{point} is recorded as fused into {into} but is live")]
    ReplacedPointLive {
        /// The fused point.
        point: MapPointId,
        /// The point it was fused into.
        into: MapPointId,
    },
    /// The chain of fusions from a point loops.
    #[error("the fusion chain from {point} loops")]
    ReplacedChainLoop {
        /// The fused point.
        point: MapPointId,
    },
}

impl Map {
    /// Checks the map's bookkeeping and returns the first inconsistency, in
    /// this order: keyframes (id order), then points (id order), then the
    /// covisibility nodes and spanning tree (id order, then the walks up the
    /// tree), then culled keyframes, issued keyframe ids and fused points.
    ///
    /// Checked:
    /// - every keyframe is stored under its own id, which the map issued; its
    ///   keypoints, descriptors, stereo entries and map-point slots agree in
    ///   number; its pose is finite;
    /// - every slot that refers to a point refers to a live point whose
    ///   observation of that keyframe is at that index, and every observation
    ///   of a live point is by a live keyframe whose slot at that index holds
    ///   the point;
    /// - every point is stored under its own id, which the map issued; its
    ///   position is finite; its weighted observation count is the sum of
    ///   its observations' weights (2 with a stereo measurement, 1 without);
    ///   if it has observations, its reference keyframe is one of them or
    ///   the keyframe that created it;
    /// - covisibility nodes exist exactly for the live keyframes; no edge
    ///   joins a keyframe to itself or has weight 0; each node's ordered
    ///   connections appear in its weight map with the same weight, once,
    ///   by decreasing weight then increasing id;
    /// - spanning tree: the first keyframe (the root, never culled) has no
    ///   parent; every other keyframe that [`Map::update_connections`] has
    ///   run on has a parent, and one never connected has neither parent nor
    ///   children (it joins the tree on its first connection); parents and
    ///   children are live and the links are mutual; walking up the parents
    ///   from any keyframe reaches the root (or, at once, an unconnected
    ///   keyframe), so there is no cycle;
    /// - every keyframe id the map issued is live or culled; culled
    ///   keyframes are not live and their chains of culled parents end, without
    ///   looping, at a live keyframe, so [`Map::pose_cw_of`] works for every
    ///   keyframe the map ever held; fused points are not live and their
    ///   fusion chains do not loop.
    ///
    /// Deliberately not checked, because the map does not maintain them:
    /// - that the reference keyframe of an observed point observes it:
    ///   [`Map::add_map_point`] does not add the creator's observation, so a
    ///   point seen only by other keyframes keeps its creator as reference
    ///   (only [`Map::erase_observation`] moves the reference, and then to an
    ///   observer);
    /// - that covisibility edges are symmetric, have weights equal to the
    ///   shared-point counts, or lead to live keyframes: as in ORB-SLAM3,
    ///   [`Map::update_connections`] rewrites one keyframe's edges and only
    ///   adds or updates the other ends of the edges it keeps, so an edge it
    ///   drops (or keeps for fewer shared points) stays, stale, at the other
    ///   end until that keyframe is updated too, and removing a keyframe
    ///   only clears the ends listed in its own node. After
    ///   `update_connections` has run on every live keyframe since the last
    ///   change, the weights are the exact shared-point counts, and so
    ///   symmetric;
    /// - that a point's normal or distances are finite (the normal of a point
    ///   seen from exactly opposite directions is undefined).
    pub fn check_invariants(&self) -> Result<(), InvariantViolation> {
        self.check_keyframes()?;
        self.check_points()?;
        self.check_covisibility()?;
        self.check_history()
    }

    fn check_keyframes(&self) -> Result<(), InvariantViolation> {
        for (&key, kf) in &self.keyframes {
            let scales = &kf.measurements.scales;
            let levels = scales.scale_factors.len();
            if [
                scales.inv_scale_factors.len(),
                scales.level_sigma2.len(),
                scales.inv_level_sigma2.len(),
                scales.features_per_level.len(),
            ]
            .iter()
            .any(|n| *n != levels)
            {
                return Err(InvariantViolation::ScaleTablesMismatch { keyframe: key });
            }
            for (index, kp) in kf.measurements.keypoints.iter().enumerate() {
                if kp.octave >= 0 && kp.octave as usize >= levels {
                    return Err(InvariantViolation::OctaveOutOfRange {
                        keyframe: key,
                        index,
                        octave: kp.octave,
                        levels,
                    });
                }
            }
            if kf.id() != key {
                return Err(InvariantViolation::KeyFrameIdMismatch {
                    key,
                    stored: kf.id(),
                });
            }
            if key.0 >= self.next_keyframe {
                return Err(InvariantViolation::UnissuedKeyFrameId {
                    keyframe: key,
                    next: self.next_keyframe,
                });
            }
            let m = &kf.measurements;
            if m.validate().is_err() {
                return Err(InvariantViolation::MeasurementsMismatch {
                    keyframe: key,
                    keypoints: m.keypoints.len(),
                    descriptors: m.descriptors.len(),
                    stereo: m.stereo.len(),
                });
            }
            if kf.map_points().len() != m.len() {
                return Err(InvariantViolation::SlotCountMismatch {
                    keyframe: key,
                    slots: kf.map_points().len(),
                    keypoints: m.len(),
                });
            }
            let pose = kf.pose_cw();
            if !(pose.rotation.coords.iter().all(|c| c.is_finite())
                && pose.translation.iter().all(|c| c.is_finite()))
            {
                return Err(InvariantViolation::NonFinitePose { keyframe: key });
            }
            for (index, point) in kf.observed_points() {
                let Some(p) = self.points.get(&point) else {
                    return Err(InvariantViolation::SlotWithoutPoint {
                        keyframe: key,
                        index,
                        point,
                    });
                };
                let observed = p.observations.get(&key).copied();
                if observed != Some(index) {
                    return Err(InvariantViolation::SlotWithoutObservation {
                        keyframe: key,
                        index,
                        point,
                        observed,
                    });
                }
            }
        }
        Ok(())
    }

    fn check_points(&self) -> Result<(), InvariantViolation> {
        for (&key, p) in &self.points {
            if p.id() != key {
                return Err(InvariantViolation::MapPointIdMismatch {
                    key,
                    stored: p.id(),
                });
            }
            if key.0 >= self.next_point {
                return Err(InvariantViolation::UnissuedMapPointId {
                    point: key,
                    next: self.next_point,
                });
            }
            if !p.position.iter().all(|c| c.is_finite()) {
                return Err(InvariantViolation::NonFinitePosition { point: key });
            }
            let mut expected = 0;
            for (&keyframe, &index) in &p.observations {
                let Some(kf) = self.keyframes.get(&keyframe) else {
                    return Err(InvariantViolation::ObservationWithoutKeyFrame {
                        point: key,
                        keyframe,
                        index,
                    });
                };
                let slot = kf.map_point(index);
                if slot != Some(key) {
                    return Err(InvariantViolation::ObservationWithoutSlot {
                        point: key,
                        keyframe,
                        index,
                        slot,
                    });
                }
                expected += observation_weight(kf, index);
            }
            if p.weighted_observations != expected {
                return Err(InvariantViolation::WeightedObservationsMismatch {
                    point: key,
                    stored: p.weighted_observations,
                    expected,
                });
            }
            let reference = p.reference_keyframe;
            if !p.observations.is_empty()
                && !p.observations.contains_key(&reference)
                && reference != p.first_keyframe
            {
                return Err(InvariantViolation::ReferenceNotObserver {
                    point: key,
                    reference,
                });
            }
        }
        Ok(())
    }

    fn check_covisibility(&self) -> Result<(), InvariantViolation> {
        if let Some(&keyframe) = self
            .keyframes
            .keys()
            .find(|k| !self.covisibility.contains_key(k))
        {
            return Err(InvariantViolation::MissingCovisibilityNode { keyframe });
        }
        if let Some(&keyframe) = self
            .covisibility
            .keys()
            .find(|k| !self.keyframes.contains_key(k))
        {
            return Err(InvariantViolation::CovisibilityNodeWithoutKeyFrame { keyframe });
        }
        let root = self.keyframes.keys().next().copied();
        for (&keyframe, node) in &self.covisibility {
            if node.weights.contains_key(&keyframe)
                || node.ordered.iter().any(|(k, _)| *k == keyframe)
            {
                return Err(InvariantViolation::CovisibilitySelfEdge { keyframe });
            }
            if let Some((&other, _)) = node.weights.iter().find(|(_, w)| **w == 0) {
                return Err(InvariantViolation::ZeroWeightEdge { keyframe, other });
            }
            for &(other, listed) in &node.ordered {
                let weight = node.weights.get(&other).copied();
                if weight != Some(listed) {
                    return Err(InvariantViolation::ConnectionWeightMismatch {
                        keyframe,
                        other,
                        listed,
                        weight,
                    });
                }
            }
            for pair in node.ordered.windows(2) {
                let ((first, w1), (second, w2)) = (pair[0], pair[1]);
                if !(w1 > w2 || (w1 == w2 && first < second)) {
                    return Err(InvariantViolation::UnsortedConnections {
                        keyframe,
                        first,
                        second,
                    });
                }
            }
            let is_root = Some(keyframe) == root;
            if node.connected || is_root {
                if node.parent.is_none() && !is_root {
                    return Err(InvariantViolation::MissingParent { keyframe });
                }
            } else if let Some(parent) = node.parent {
                return Err(InvariantViolation::UnconnectedWithParent { keyframe, parent });
            } else if let Some(&child) = node.children.first() {
                return Err(InvariantViolation::UnconnectedWithChild { keyframe, child });
            }
            if let Some(parent) = node.parent {
                if is_root {
                    return Err(InvariantViolation::RootHasParent {
                        root: keyframe,
                        parent,
                    });
                }
                let Some(parent_node) = self.covisibility.get(&parent) else {
                    return Err(InvariantViolation::ParentNotLive { keyframe, parent });
                };
                if !parent_node.children.contains(&keyframe) {
                    return Err(InvariantViolation::ParentWithoutChild { keyframe, parent });
                }
            }
            for &child in &node.children {
                let Some(child_node) = self.covisibility.get(&child) else {
                    return Err(InvariantViolation::ChildNotLive { keyframe, child });
                };
                if child_node.parent != Some(keyframe) {
                    return Err(InvariantViolation::ChildWithOtherParent {
                        keyframe,
                        child,
                        parent: child_node.parent,
                    });
                }
            }
        }
        self.check_tree_reaches_root(root)
    }

    /// Walks up the parents from every keyframe, with a step bound, after
    /// `check_covisibility` has checked the links: each walk must end
    /// at the root or start at an unconnected keyframe (which has no
    /// children). Keyframes known to reach the root end later walks early,
    /// so this is linear in the number of keyframes.
    fn check_tree_reaches_root(&self, root: Option<KeyFrameId>) -> Result<(), InvariantViolation> {
        let mut reaches_root: BTreeSet<KeyFrameId> = root.into_iter().collect();
        for &keyframe in self.covisibility.keys() {
            let mut path = Vec::new();
            let mut current = keyframe;
            while !reaches_root.contains(&current) {
                let Some(parent) = self.covisibility.get(&current).and_then(|n| n.parent) else {
                    break;
                };
                path.push(current);
                if path.len() > self.covisibility.len() {
                    return Err(InvariantViolation::SpanningTreeCycle { keyframe });
                }
                current = parent;
            }
            if reaches_root.contains(&current) {
                reaches_root.extend(path);
            }
        }
        Ok(())
    }

    fn check_history(&self) -> Result<(), InvariantViolation> {
        for &keyframe in self.culled.keys() {
            if self.keyframes.contains_key(&keyframe) {
                return Err(InvariantViolation::CulledKeyFrameLive { keyframe });
            }
            let mut current = keyframe;
            for _ in 0..=self.culled.len() {
                match self.culled.get(&current) {
                    Some(culled) => current = culled.parent,
                    None => break,
                }
            }
            if self.culled.contains_key(&current) {
                return Err(InvariantViolation::CulledChainLoop { keyframe });
            }
            if !self.keyframes.contains_key(&current) {
                return Err(InvariantViolation::CulledChainBroken {
                    keyframe,
                    missing: current,
                });
            }
        }
        // Every issued id is live or culled: walk the known ids of each
        // range in order (bounded by the map's size, whatever the ranges
        // claim) and report the first gap.
        for range in self.issued_keyframe_ranges() {
            let (from, to) = (KeyFrameId(range.start), KeyFrameId(range.end));
            let mut known: Vec<u64> = self
                .keyframes
                .range(from..to)
                .map(|(k, _)| k.0)
                .chain(self.culled.range(from..to).map(|(k, _)| k.0))
                .collect();
            known.sort_unstable();
            let mut expected = range.start;
            for id in known {
                if id != expected {
                    break;
                }
                expected += 1;
            }
            if expected < range.end {
                return Err(InvariantViolation::KeyFrameLost {
                    keyframe: KeyFrameId(expected),
                });
            }
        }
        for (&point, &into) in &self.replaced {
            if self.points.contains_key(&point) {
                return Err(InvariantViolation::ReplacedPointLive { point, into });
            }
            let mut current = point;
            for _ in 0..=self.replaced.len() {
                match self.replaced.get(&current) {
                    Some(next) => current = *next,
                    None => break,
                }
            }
            if self.replaced.contains_key(&current) {
                return Err(InvariantViolation::ReplacedChainLoop { point });
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::{UnitQuaternion, Vector3};

    use super::InvariantViolation;
    use crate::map::{KeyFrameId, Map, MapPointId, PointDescriptor};
    use crate::optim::Se3;

    use crate::map::tests_support::{measurements, DIM};

    /// Three keyframes all seeing the same four points, connected.
    fn small_map() -> (Map, Vec<KeyFrameId>, Vec<MapPointId>) {
        let mut map = Map::new();
        let kfs: Vec<KeyFrameId> = (0..3)
            .map(|k| {
                let pose = Se3::new(
                    UnitQuaternion::identity(),
                    Vector3::new(-(k as f64), 0.0, 0.0),
                );
                map.add_keyframe(k, k as f64, pose, measurements(4))
                    .expect("keyframe")
            })
            .collect();
        let points: Vec<MapPointId> = (0..4)
            .map(|i| {
                let p = map
                    .add_map_point(
                        Vector3::new(i as f64, 0.0, 5.0),
                        PointDescriptor::Float(vec![0.0; DIM].into()),
                        kfs[0],
                    )
                    .expect("point");
                for kf in &kfs {
                    map.add_observation(p, *kf, i).expect("observation");
                }
                p
            })
            .collect();
        for kf in &kfs {
            map.update_connections(*kf);
        }
        (map, kfs, points)
    }

    #[test]
    fn a_consistent_map_passes_and_each_corruption_is_named() {
        let (map, kfs, _) = small_map();
        assert_eq!(map.check_invariants(), Ok(()));
        assert_eq!(map.parent(kfs[1]), Some(kfs[0]), "the tree is populated");
        assert_eq!(map.covisibility_weight(kfs[1], kfs[2]), 4);

        // A slot pointing to a point that does not exist.
        let (mut map, kfs, _) = small_map();
        let ghost = MapPointId(99);
        map.keyframes
            .get_mut(&kfs[1])
            .expect("kf")
            .set_map_point(3, Some(ghost));
        assert_eq!(
            map.check_invariants(),
            Err(InvariantViolation::SlotWithoutPoint {
                keyframe: kfs[1],
                index: 3,
                point: ghost,
            })
        );

        // A slot emptied behind the point's back.
        let (mut map, kfs, points) = small_map();
        map.keyframes
            .get_mut(&kfs[2])
            .expect("kf")
            .set_map_point(1, None);
        assert_eq!(
            map.check_invariants(),
            Err(InvariantViolation::ObservationWithoutSlot {
                point: points[1],
                keyframe: kfs[2],
                index: 1,
                slot: None,
            })
        );

        // A wrong weighted count: keypoint 0 is stereo, so three keyframes weigh 6.
        let (mut map, _, points) = small_map();
        map.points
            .get_mut(&points[0])
            .expect("p")
            .weighted_observations = 3;
        assert_eq!(
            map.check_invariants(),
            Err(InvariantViolation::WeightedObservationsMismatch {
                point: points[0],
                stored: 3,
                expected: 6,
            })
        );

        // A non-finite position.
        let (mut map, _, points) = small_map();
        map.points.get_mut(&points[2]).expect("p").position.x = f64::NAN;
        assert_eq!(
            map.check_invariants(),
            Err(InvariantViolation::NonFinitePosition { point: points[2] })
        );

        // A connection listed with a weight its weight map disagrees with.
        let (mut map, kfs, _) = small_map();
        let node = map.covisibility.get_mut(&kfs[0]).expect("node");
        node.ordered[0].1 = 7;
        let other = node.ordered[0].0;
        assert_eq!(
            map.check_invariants(),
            Err(InvariantViolation::ConnectionWeightMismatch {
                keyframe: kfs[0],
                other,
                listed: 7,
                weight: Some(4),
            })
        );

        // A one-sided spanning-tree link: the parent forgets its child.
        let (mut map, kfs, _) = small_map();
        let parent = map.parent(kfs[2]).expect("parent");
        map.covisibility
            .get_mut(&parent)
            .expect("node")
            .children
            .remove(&kfs[2]);
        assert_eq!(
            map.check_invariants(),
            Err(InvariantViolation::ParentWithoutChild {
                keyframe: kfs[2],
                parent,
            })
        );

        // A covisibility node left behind by a removed keyframe.
        let (mut map, kfs, _) = small_map();
        let removed = map.keyframes.remove(&kfs[2]).expect("kf");
        for (index, point) in removed.observed_points() {
            if let Some(p) = map.points.get_mut(&point) {
                p.observations.remove(&kfs[2]);
                p.weighted_observations -= super::observation_weight(&removed, index);
            }
        }
        assert_eq!(
            map.check_invariants(),
            Err(InvariantViolation::CovisibilityNodeWithoutKeyFrame { keyframe: kfs[2] })
        );
    }

    #[test]
    fn spanning_tree_and_culling_history_corruptions_are_named() {
        // An unconnected keyframe (no parent, no children) is consistent.
        let (mut map, kfs, _) = small_map();
        let pose = Se3::new(UnitQuaternion::identity(), Vector3::new(-3.0, 0.0, 0.0));
        let pending = map
            .add_keyframe(3, 3.0, pose, measurements(4))
            .expect("keyframe");
        assert_eq!(map.check_invariants(), Ok(()));
        assert_eq!(map.parent(pending), None);
        // ... until it is given a child.
        map.covisibility
            .get_mut(&pending)
            .expect("node")
            .children
            .insert(kfs[2]);
        map.covisibility
            .get_mut(&kfs[0])
            .expect("node")
            .children
            .remove(&kfs[2]);
        map.covisibility.get_mut(&kfs[2]).expect("node").parent = Some(pending);
        assert_eq!(
            map.check_invariants(),
            Err(InvariantViolation::UnconnectedWithChild {
                keyframe: pending,
                child: kfs[2],
            })
        );

        // A connected keyframe that lost its parent.
        let (mut map, kfs, _) = small_map();
        assert_eq!(map.parent(kfs[2]), Some(kfs[0]));
        map.covisibility.get_mut(&kfs[2]).expect("node").parent = None;
        map.covisibility
            .get_mut(&kfs[0])
            .expect("node")
            .children
            .remove(&kfs[2]);
        assert_eq!(
            map.check_invariants(),
            Err(InvariantViolation::MissingParent { keyframe: kfs[2] })
        );

        // A keyframe with a parent but marked as never connected.
        let (mut map, kfs, _) = small_map();
        map.covisibility.get_mut(&kfs[1]).expect("node").connected = false;
        assert_eq!(
            map.check_invariants(),
            Err(InvariantViolation::UnconnectedWithParent {
                keyframe: kfs[1],
                parent: kfs[0],
            })
        );

        // Two keyframes that are each other's parent, with mutual links.
        let (mut map, kfs, _) = small_map();
        map.covisibility
            .get_mut(&kfs[0])
            .expect("node")
            .children
            .clear();
        for (a, b) in [(kfs[1], kfs[2]), (kfs[2], kfs[1])] {
            let node = map.covisibility.get_mut(&a).expect("node");
            node.parent = Some(b);
            node.children = [b].into_iter().collect();
        }
        assert_eq!(
            map.check_invariants(),
            Err(InvariantViolation::SpanningTreeCycle { keyframe: kfs[1] })
        );

        // A culled keyframe whose chain ends at a keyframe with no record.
        let (mut map, kfs, _) = small_map();
        map.erase_keyframe(kfs[1]).expect("erase");
        map.erase_keyframe(kfs[2]).expect("erase");
        assert_eq!(map.check_invariants(), Ok(()));
        map.culled.get_mut(&kfs[2]).expect("record").parent = kfs[1];
        map.culled.remove(&kfs[1]);
        assert_eq!(
            map.check_invariants(),
            Err(InvariantViolation::CulledChainBroken {
                keyframe: kfs[2],
                missing: kfs[1],
            })
        );

        // A removed keyframe that left no record.
        let (mut map, kfs, _) = small_map();
        map.erase_keyframe(kfs[2]).expect("erase");
        map.culled.remove(&kfs[2]);
        assert_eq!(
            map.check_invariants(),
            Err(InvariantViolation::KeyFrameLost { keyframe: kfs[2] })
        );
    }
}
