//! The atlas: every map a run has made (ORB-SLAM3's `Atlas`).
//!
//! Tracking works in the active map, the newest. When it stays lost, the
//! system starts a new map instead of waiting forever; older maps are kept,
//! with their keyframes and points, so the frames tracked in them stay in
//! the trajectory. Loop closing merges the active map into an older one
//! when it finds a place they share (ORB-SLAM3's `MergeLocal`): the older
//! map absorbs the active one's keyframes and points and becomes active
//! again ([`Atlas::merge_active_into`]); the absorbed map stays in the
//! list, empty, with [`AtlasMap::merged_into`] set.
//!
//! Each map issues its keyframe and point ids from its own base
//! ([`Map::with_id_base`]: map `i` from `i·2⁴⁰`), so ids stay unique over
//! the atlas and survive a merge.

use crate::map::{Map, SharedMap};

/// A map's index in the atlas, in creation order.
pub type MapIndex = usize;

/// One map of the atlas.
#[derive(Debug)]
pub struct AtlasMap {
    /// Its index in the atlas.
    pub index: MapIndex,
    /// The map, shared with local mapping.
    pub map: SharedMap,
    /// Index of the first input frame processed in it.
    pub first_frame: usize,
    /// The map it was merged into, if it was.
    pub merged_into: Option<MapIndex>,
    /// Whether it came from a map file: its frame is the trajectory's
    /// world frame (no anchoring at the first tracked frame).
    pub loaded: bool,
}

/// Ids of map `index` start at `index · 2⁴⁰`.
fn id_base(index: MapIndex) -> u64 {
    (index as u64) << 40
}

/// Every map made so far; the last one is active.
#[derive(Debug)]
pub struct Atlas {
    maps: Vec<AtlasMap>,
    active: MapIndex,
}

impl Default for Atlas {
    fn default() -> Self {
        Self::new()
    }
}

impl Atlas {
    /// An atlas with one empty map, starting at frame 0.
    pub fn new() -> Self {
        Self {
            maps: vec![AtlasMap {
                index: 0,
                map: Map::with_id_base(id_base(0)).into_shared(),
                first_frame: 0,
                merged_into: None,
                loaded: false,
            }],
            active: 0,
        }
    }

    /// An atlas of loaded maps (`(index, first frame, merged into, map)`,
    /// indices 0.. in order), `active` active. `None` when the indices are
    /// not 0.. in order, `active` is not one of them, or it was merged.
    pub fn from_loaded(
        maps: Vec<(MapIndex, usize, Option<MapIndex>, Map)>,
        active: MapIndex,
    ) -> Option<Self> {
        let n = maps.len();
        let mut out = Vec::with_capacity(n);
        for (i, (index, first_frame, merged_into, map)) in maps.into_iter().enumerate() {
            if index != i || merged_into.is_some_and(|m| m >= n || m == i) {
                return None;
            }
            out.push(AtlasMap {
                index,
                map: map.into_shared(),
                first_frame,
                merged_into,
                loaded: true,
            });
        }
        match out.get(active) {
            Some(m) if m.merged_into.is_none() => Some(Self { maps: out, active }),
            _ => None,
        }
    }

    /// The active map.
    pub fn active(&self) -> &AtlasMap {
        // `active` always indexes `maps`, which is never empty: `new` makes
        // one and nothing removes any.
        &self.maps[self.active]
    }

    /// The maps loop closing may merge the active one with: every other
    /// map not merged already.
    pub fn mergeable(&self) -> impl Iterator<Item = &AtlasMap> {
        self.maps
            .iter()
            .filter(|m| m.index != self.active && m.merged_into.is_none())
    }

    /// Records that the active map was absorbed into `into`, which becomes
    /// active; returns the absorbed map's index, or `None` (nothing
    /// changed) when `into` is the active map, merged or unknown.
    pub fn merge_active_into(&mut self, into: MapIndex) -> Option<MapIndex> {
        let target = self.maps.get(into)?;
        if into == self.active || target.merged_into.is_some() {
            return None;
        }
        let merged = self.active;
        self.maps[merged].merged_into = Some(into);
        self.active = into;
        Some(merged)
    }

    /// Adds an empty map, active from frame `first_frame`; returns its index.
    pub fn start_new_map(&mut self, first_frame: usize) -> MapIndex {
        let index = self.maps.len();
        self.maps.push(AtlasMap {
            index,
            map: Map::with_id_base(id_base(index)).into_shared(),
            first_frame,
            merged_into: None,
            loaded: false,
        });
        self.active = index;
        index
    }

    /// Every map, oldest first.
    pub fn maps(&self) -> &[AtlasMap] {
        &self.maps
    }

    /// The map with `index`.
    pub fn get(&self, index: MapIndex) -> Option<&AtlasMap> {
        self.maps.get(index)
    }
}

#[cfg(test)]
mod tests {
    use super::Atlas;

    #[test]
    fn new_maps_become_active_and_old_ones_stay() {
        let mut atlas = Atlas::new();
        assert_eq!(atlas.active().index, 0);
        let second = atlas.start_new_map(17);
        assert_eq!(second, 1);
        assert_eq!(atlas.active().index, 1);
        assert_eq!(atlas.active().first_frame, 17);
        assert_eq!(atlas.maps().len(), 2);
        assert!(atlas.get(0).is_some());
        assert!(atlas.get(2).is_none());
    }

    #[test]
    fn merging_makes_the_older_map_active_and_marks_the_absorbed_one() {
        let mut atlas = Atlas::new();
        atlas.start_new_map(10);
        assert_eq!(atlas.mergeable().map(|m| m.index).collect::<Vec<_>>(), [0]);
        assert_eq!(atlas.merge_active_into(1), None, "the active map itself");
        assert_eq!(atlas.merge_active_into(5), None, "no such map");
        assert_eq!(atlas.merge_active_into(0), Some(1));
        assert_eq!(atlas.active().index, 0);
        assert_eq!(atlas.get(1).and_then(|m| m.merged_into), Some(0));
        assert_eq!(atlas.mergeable().count(), 0);
        // A new map after a merge is active, and the absorbed one stays out.
        assert_eq!(atlas.start_new_map(50), 2);
        assert_eq!(atlas.mergeable().map(|m| m.index).collect::<Vec<_>>(), [0]);
    }
}
