//! A read-only copy of part of a map, for work that should not hold the
//! map's lock while it runs (the loop and merge checks).

use super::{KeyFrameId, Map, MapPointId};

impl Map {
    /// A copy of keyframes `keyframes` (with their covisibility entries) and
    /// map points `points`, under the same ids; ids that are not live here
    /// are left out, and points are taken by exact id (not through
    /// [`Map::resolve_point`]). What is copied is whole (a keyframe's
    /// measurements, a point's observations), so every read of those items
    /// answers as in this map; but observations and covisibility entries
    /// still name keyframes that were not copied, so the excerpt is for
    /// reading only: its [invariants](Map::check_invariants) do not hold.
    ///
    /// The copy shares the keyframes' measurements and the points'
    /// descriptors (reference counts, not copies of their values) and
    /// copies the rest: a keyframe's point associations, a point's
    /// observations. Made under a read lock, it lets a check of tens of
    /// milliseconds run with no lock held (snapshot, compute, apply).
    pub fn excerpt(&self, keyframes: &[KeyFrameId], points: &[MapPointId]) -> Map {
        let mut excerpt = Map {
            next_keyframe: self.next_keyframe,
            next_point: self.next_point,
            id_base: self.id_base,
            closed_keyframe_ranges: self.closed_keyframe_ranges.clone(),
            ..Map::default()
        };
        for id in keyframes {
            if let Some(keyframe) = self.keyframes.get(id) {
                excerpt.keyframes.insert(*id, keyframe.clone());
                if let Some(node) = self.covisibility.get(id) {
                    excerpt.covisibility.insert(*id, node.clone());
                }
            }
        }
        for id in points {
            if let Some(point) = self.points.get(id) {
                excerpt.points.insert(*id, point.clone());
            }
        }
        excerpt
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests_support::small_map;
    use super::*;
    use crate::optim::{LieGroup, Se3};

    #[test]
    fn an_excerpt_answers_reads_of_what_it_copied_as_the_map_does() {
        let map = small_map(Map::new(), 5);
        let keyframes: Vec<KeyFrameId> = map.keyframes().map(|kf| kf.id()).collect();
        let chosen = [keyframes[1], keyframes[3]];
        let points: Vec<MapPointId> = map
            .keyframe(keyframes[3])
            .map(|kf| kf.observed_points().map(|(_, p)| p).collect())
            .unwrap_or_default();
        assert_eq!(points.len(), 40, "keyframe 3 shares 20 points each way");
        let unknown = MapPointId(u64::MAX);
        let excerpt = map.excerpt(&chosen, &[&points[..], &[unknown]].concat());

        assert_eq!(excerpt.keyframe_count(), 2);
        assert_eq!(excerpt.map_point_count(), 40, "the unknown id is left out");
        for id in chosen {
            let (Ok(original), Ok(copy)) = (map.keyframe(id), excerpt.keyframe(id)) else {
                panic!("keyframe {id:?} missing");
            };
            assert_eq!(copy.pose_cw(), original.pose_cw());
            assert_eq!(copy.measurements, original.measurements);
            assert_eq!(
                copy.observed_points().collect::<Vec<_>>(),
                original.observed_points().collect::<Vec<_>>()
            );
            assert_eq!(excerpt.best_covisible(id, 10), map.best_covisible(id, 10));
            assert_eq!(excerpt.pose_cw_of(id).ok(), map.pose_cw_of(id).ok());
        }
        for id in &points {
            let (Ok(original), Ok(copy)) = (map.map_point(*id), excerpt.map_point(*id)) else {
                panic!("point {id:?} missing");
            };
            assert_eq!(copy.position, original.position);
            assert_eq!(copy.descriptor, original.descriptor);
            assert_eq!(copy.observation_count(), original.observation_count());
        }
        assert!(excerpt.keyframe(keyframes[0]).is_err(), "not copied");
        let new_id = {
            let mut copy = map.excerpt(&[], &[]);
            copy.add_keyframe(
                9,
                9.0,
                Se3::identity(),
                super::super::tests_support::measurements(1),
            )
        };
        let next = {
            let mut original = small_map(Map::new(), 5);
            original.add_keyframe(
                9,
                9.0,
                Se3::identity(),
                super::super::tests_support::measurements(1),
            )
        };
        assert_eq!(new_id.ok(), next.ok(), "ids continue from the map's");
    }
}
