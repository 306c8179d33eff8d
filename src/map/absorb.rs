//! Map merging on the map's side (ORB-SLAM3's `MergeLocal` moves a map's
//! keyframes and points into another's world): one map absorbs another,
//! moved by a similarity (rigid for stereo and RGB-D, with the scale of a
//! monocular map too), and their spanning trees are joined.
//!
//! Ids are never renumbered: the maps of an atlas issue disjoint ids
//! ([`Map::with_id_base`]), so whatever refers to the absorbed map's
//! keyframes and points (tracking's last frame, local mapping's recent
//! points, the frame records) still refers to the same entities after
//! the merge. Fusing the duplicates the two maps hold of the same place is
//! the loop correction's job (see `loop_closing::correct_loop`).

use std::collections::BTreeSet;

use crate::optim::{LieGroup, Sim3};

use super::error::{MapError, Result};
use super::ids::KeyFrameId;
use super::Map;

impl Map {
    /// Moves every keyframe, point and graph edge of `other` into this map.
    ///
    /// `t_self_other` takes `other`'s world frame to this map's:
    /// `X_self = t_self_other · X_other = s·R·X_other + t`. A keyframe's
    /// camera keeps its place in `other`'s scene, measured in this map's
    /// units: its `T_cw` becomes `s·T_cw·t_self_other⁻¹` (a rigid motion:
    /// `(R_cw·Rᵀ, s·t_cw − R_cw·Rᵀ·t)`), a culled keyframe's pose relative
    /// to its parent keeps its rotation and scales its translation, and a
    /// point's scale-invariance distances scale with it (ORB-SLAM3's
    /// `MergeLocal` with a monocular map's `g2o::Sim3`). With a scale other
    /// than 1, `other` must hold no depth measurement
    /// ([`MapError::ScaledDepths`]): a stereo or RGB-D map's scale is the
    /// sensor's. The spanning trees are joined at
    /// `join = (other_kf, self_kf)`: the path from `other_kf` up to its
    /// root is reversed and `other_kf` becomes a child of `self_kf`
    /// (ORB-SLAM3's `ChangeParent` in `MergeLocal`), so this map's root
    /// stays the root.
    ///
    /// `other` is left empty. Nothing changes, in either map, when the ids
    /// overlap ([`MapError::IdCollision`]), a join keyframe is not live
    /// ([`MapError::JoinAtUnknownKeyFrame`]) or depths would be scaled.
    pub fn absorb(
        &mut self,
        other: &mut Map,
        t_self_other: &Sim3,
        join: (KeyFrameId, KeyFrameId),
    ) -> Result<()> {
        let (other_kf, self_kf) = join;
        if !other.keyframes.contains_key(&other_kf) {
            return Err(MapError::JoinAtUnknownKeyFrame(other_kf));
        }
        if !self.keyframes.contains_key(&self_kf) {
            return Err(MapError::JoinAtUnknownKeyFrame(self_kf));
        }
        self.check_disjoint(other)?;
        let scale = t_self_other.scale;
        if scale != 1.0 {
            let with_depth = other
                .keyframes
                .values()
                .find(|k| k.measurements.stereo.iter().any(Option::is_some));
            if let Some(kf) = with_depth {
                return Err(MapError::ScaledDepths {
                    keyframe: kf.id(),
                    scale,
                });
            }
        }
        let mut other = std::mem::take(other);
        other.join_tree_at(other_kf);
        let to_other = t_self_other.inverse();
        for (id, mut kf) in std::mem::take(&mut other.keyframes) {
            let moved = Sim3::from_se3(&kf.pose_cw()).compose(&to_other);
            kf.set_pose_cw(moved.to_se3_unscaled());
            self.keyframes.insert(id, kf);
        }
        for (id, mut point) in std::mem::take(&mut other.points) {
            point.position = t_self_other.transform_point(&point.position);
            point.normal = t_self_other.rotation * point.normal;
            point.min_distance *= scale;
            point.max_distance *= scale;
            self.points.insert(id, point);
        }
        for culled in other.culled.values_mut() {
            culled.relative_pose.translation *= scale;
        }
        self.covisibility
            .extend(std::mem::take(&mut other.covisibility));
        // Culled keyframes keep their pose relative to their parent, which
        // moves with them.
        self.culled.extend(std::mem::take(&mut other.culled));
        self.replaced.extend(std::mem::take(&mut other.replaced));
        let mine = self.id_base..self.next_keyframe;
        let theirs = other.id_base..other.next_keyframe;
        self.closed_keyframe_ranges
            .extend(std::mem::take(&mut other.closed_keyframe_ranges));
        if other.id_base > self.id_base {
            // New ids continue in the range with room above them.
            self.closed_keyframe_ranges.push(mine);
            self.id_base = other.id_base;
            self.next_keyframe = other.next_keyframe;
            self.next_point = other.next_point;
        } else {
            self.closed_keyframe_ranges.push(theirs);
        }
        self.set_parent(other_kf, self_kf);
        Ok(())
    }

    /// Fails when `other` holds an id this map holds or has issued.
    fn check_disjoint(&self, other: &Map) -> Result<()> {
        let mine = self.issued_keyframe_ranges();
        for id in other.keyframes.keys().chain(other.culled.keys()) {
            if mine.iter().any(|r| r.contains(&id.0)) || self.keyframes.contains_key(id) {
                return Err(MapError::IdCollision {
                    what: "keyframe",
                    id: id.0,
                });
            }
        }
        for id in other.points.keys().chain(other.replaced.keys()) {
            if self.points.contains_key(id) || self.replaced.contains_key(id) {
                return Err(MapError::IdCollision {
                    what: "map point",
                    id: id.0,
                });
            }
        }
        Ok(())
    }

    /// Makes `keyframe` the root of its spanning tree by reversing the path
    /// from it to the root; it is then left without a parent, marked
    /// connected, ready to be attached under another tree.
    fn join_tree_at(&mut self, keyframe: KeyFrameId) {
        let mut path = vec![keyframe];
        let mut seen = BTreeSet::from([keyframe]);
        while let Some(parent) = path.last().and_then(|k| self.parent(*k)) {
            if !seen.insert(parent) {
                break;
            }
            path.push(parent);
        }
        for pair in path.windows(2) {
            let (child, parent) = (pair[0], pair[1]);
            if let Some(node) = self.covisibility.get_mut(&parent) {
                node.children.remove(&child);
            }
            if let Some(node) = self.covisibility.get_mut(&child) {
                node.parent = None;
            }
        }
        for pair in path.windows(2) {
            let (new_parent, new_child) = (pair[0], pair[1]);
            self.set_parent(new_child, new_parent);
        }
        for k in &path {
            if let Some(node) = self.covisibility.get_mut(k) {
                node.connected = true;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::{UnitQuaternion, Vector3};

    use crate::map::tests_support::{measurements, small_map, small_map_with};
    use crate::map::{KeyFrameId, Map, MapError};
    use crate::optim::{LieGroup, Se3, Sim3};

    #[test]
    fn absorbed_map_moves_by_the_transform_and_passes_the_invariants() {
        let mut old = small_map(Map::new(), 4);
        let mut new = small_map(Map::with_id_base(1 << 40), 5);
        let t = Se3::new(
            UnitQuaternion::from_euler_angles(0.1, -0.2, 0.3),
            Vector3::new(1.0, -2.0, 0.5),
        );
        let join_other = KeyFrameId((1 << 40) + 3);
        let pose_before = new.pose_cw_of(join_other).map_err(|e| e.to_string());
        let point_before: Vec<_> = new.map_points().map(|p| (p.id(), p.position)).collect();
        let (kfs, points) = (
            old.keyframe_count() + new.keyframe_count(),
            old.map_point_count() + new.map_point_count(),
        );
        assert!(old
            .absorb(&mut new, &Sim3::from_se3(&t), (join_other, KeyFrameId(2)))
            .is_ok());
        assert_eq!(new.keyframe_count(), 0);
        assert_eq!(old.keyframe_count(), kfs);
        assert_eq!(old.map_point_count(), points);
        assert_eq!(old.check_invariants(), Ok(()));
        let after = old.pose_cw_of(join_other).map_err(|e| e.to_string());
        let expected = pose_before.map(|p| p.compose(&t.inverse()));
        let (Ok(after), Ok(expected)) = (after, expected) else {
            panic!("join keyframe lost");
        };
        assert!((after.translation - expected.translation).norm() < 1e-12);
        for (id, before) in point_before {
            let p = old.map_point(id).map(|p| p.position);
            assert_eq!(p, Ok(t.transform_point(&before)));
        }
        // The absorbed tree hangs under the join keyframe, re-rooted there.
        assert_eq!(old.parent(join_other), Some(KeyFrameId(2)));
        assert_eq!(
            old.parent(KeyFrameId(1 << 40)),
            Some(KeyFrameId((1 << 40) + 1))
        );
        // New ids continue above the absorbed map's.
        let id = old.add_keyframe(99, 9.9, Se3::identity(), measurements(3));
        assert_eq!(id, Ok(KeyFrameId((1 << 40) + 5)));
        assert_eq!(old.check_invariants(), Ok(()));
    }

    #[test]
    fn overlapping_ids_are_refused_and_nothing_changes() {
        let mut a = small_map(Map::new(), 3);
        let mut b = small_map(Map::new(), 3);
        let before = a.keyframe_count();
        let r = a.absorb(&mut b, &Sim3::identity(), (KeyFrameId(1), KeyFrameId(1)));
        assert!(matches!(r, Err(MapError::IdCollision { .. })), "{r:?}");
        assert_eq!(a.keyframe_count(), before);
        assert_eq!(b.keyframe_count(), 3);
        let mut c = small_map(Map::with_id_base(100), 2);
        let r = a.absorb(&mut c, &Sim3::identity(), (KeyFrameId(7), KeyFrameId(0)));
        assert_eq!(r, Err(MapError::JoinAtUnknownKeyFrame(KeyFrameId(7))));
    }

    /// Every observation of the absorbed monocular map, in its keyframe's
    /// camera: `(keyframe, point, X_c)`.
    fn camera_points(map: &Map) -> Vec<(KeyFrameId, crate::map::MapPointId, Vector3<f64>)> {
        let mut out = Vec::new();
        for kf in map.keyframes() {
            for (_, p) in kf.observed_points() {
                if let Ok(point) = map.map_point(p) {
                    out.push((kf.id(), p, kf.pose_cw().transform_point(&point.position)));
                }
            }
        }
        out
    }

    #[test]
    fn a_monocular_map_absorbed_in_sim3_keeps_every_view_scaled_and_its_culled_keyframes() {
        let mut old = small_map(Map::new(), 4);
        let mut new = small_map_with(Map::with_id_base(1 << 40), 6, false);
        let culled = KeyFrameId((1 << 40) + 2);
        let culled_before = new.pose_cw_of(culled).map_err(|e| e.to_string());
        assert_eq!(new.erase_keyframe(culled), Ok(()));
        let s = 2.5;
        let t = Sim3::new(
            UnitQuaternion::from_euler_angles(0.2, 0.1, -0.3),
            Vector3::new(-1.0, 3.0, 0.25),
            s,
        );
        let views_before = camera_points(&new);
        let distances_before: Vec<_> = new
            .map_points()
            .map(|p| (p.id(), p.min_distance, p.max_distance))
            .collect();
        let join_other = KeyFrameId((1 << 40) + 4);
        assert_eq!(
            old.absorb(&mut new, &t, (join_other, KeyFrameId(1))),
            Ok(())
        );
        assert_eq!(old.check_invariants(), Ok(()));
        // Each camera sees each of its points in the same direction, s times
        // as far: the same pixels, in the older map's units.
        let views_after = camera_points(&old);
        assert!(!views_before.is_empty());
        for (kf, p, before) in &views_before {
            let after = views_after
                .iter()
                .find(|(k, q, _)| k == kf && q == p)
                .map(|(_, _, x)| *x);
            let Some(after) = after else {
                panic!("{kf} lost its view of {p}");
            };
            assert!(
                (after - before * s).norm() < 1e-9,
                "{kf} {p}: {after} vs {before}"
            );
        }
        for (id, min, max) in distances_before {
            let point = old.map_point(id).map(|p| (p.min_distance, p.max_distance));
            assert_eq!(point, Ok((min * s, max * s)));
        }
        // The culled keyframe's centre moves with the map: X_self = t·X_other.
        let (Ok(before), Ok(after)) = (culled_before, old.pose_cw_of(culled)) else {
            panic!("culled keyframe lost");
        };
        let centre = t.transform_point(&before.inverse().translation);
        assert!((after.inverse().translation - centre).norm() < 1e-9);
        assert!(
            after
                .rotation
                .angle_to(&(before.rotation * t.rotation.inverse()))
                < 1e-9
        );
    }

    #[test]
    fn a_map_with_depths_is_not_scaled() {
        let mut old = small_map(Map::new(), 3);
        let mut new = small_map(Map::with_id_base(1 << 40), 3);
        let t = Sim3::new(UnitQuaternion::identity(), Vector3::zeros(), 2.0);
        let r = old.absorb(&mut new, &t, (KeyFrameId(1 << 40), KeyFrameId(0)));
        assert!(matches!(r, Err(MapError::ScaledDepths { .. })), "{r:?}");
        assert_eq!(new.keyframe_count(), 3);
        assert_eq!(old.keyframe_count(), 3);
    }
}
