//! The atlas: every map a run has made (ORB-SLAM3's `Atlas`).
//!
//! Tracking works in the active map, the newest. When it stays lost, the
//! system starts a new map instead of waiting forever; older maps are kept,
//! with their keyframes and points, so the frames tracked in them stay in
//! the trajectory. Loop closing will merge a map into another (ORB-SLAM3's
//! `MergeLocal`) through [`Atlas::maps`]: the seam is the map id each frame
//! record carries, and the anchoring [`crate::system::StereoSlam::trajectory`]
//! computes from it, which a merge would replace by the merge transform.

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
}

/// Every map made so far; the last one is active.
#[derive(Debug)]
pub struct Atlas {
    maps: Vec<AtlasMap>,
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
                map: Map::new().into_shared(),
                first_frame: 0,
            }],
        }
    }

    /// The active map.
    pub fn active(&self) -> &AtlasMap {
        // `maps` is never empty: `new` makes one and nothing removes any.
        &self.maps[self.maps.len() - 1]
    }

    /// Adds an empty map, active from frame `first_frame`; returns its index.
    pub fn start_new_map(&mut self, first_frame: usize) -> MapIndex {
        let index = self.maps.len();
        self.maps.push(AtlasMap {
            index,
            map: Map::new().into_shared(),
            first_frame,
        });
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
}
