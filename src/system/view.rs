//! What a live viewer shows, copied out of the system between frames: the
//! last frame's keypoints and which of them track map points, and every
//! map's points and keyframes in the trajectory's world frame. Each copy
//! takes the maps' read locks briefly and one at a time; drawing happens
//! elsewhere, from these copies.

use crate::error::SlamError;
use crate::optim::{LieGroup, Se3};

use super::atlas::MapIndex;
use super::SlamSystem;

/// The keypoints of the last tracked frame.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameView {
    /// The frame's index in the input sequence.
    pub index: usize,
    /// Keypoint positions (x, y) in pixels of the full-resolution image.
    pub keypoints: Vec<[f32; 2]>,
    /// Whether each keypoint tracks a map point (an inlier of the pose).
    pub tracked: Vec<bool>,
}

/// One map's contents, in the trajectory's world frame.
#[derive(Debug, Clone, PartialEq)]
pub struct MapView {
    /// The atlas map.
    pub map: MapIndex,
    /// Whether it is the map tracking works in now.
    pub active: bool,
    /// Its live points' positions (metres).
    pub points: Vec<[f32; 3]>,
    /// Its live keyframes, in creation order.
    pub keyframes: Vec<KeyFrameView>,
}

/// A keyframe's place in the world.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KeyFrameView {
    /// Its identifier (unique within its map).
    pub id: u64,
    /// The input frame it was made from.
    pub frame: usize,
    /// `T_wc`.
    pub pose_wc: Se3,
}

impl SlamSystem {
    /// The last tracked frame's keypoints; `None` before the first one.
    pub fn frame_view(&self) -> Option<FrameView> {
        let frame = self.tracker.last_frame()?;
        Some(FrameView {
            index: frame.index,
            keypoints: frame
                .features
                .keypoints
                .iter()
                .map(|k| [k.x, k.y])
                .collect(),
            tracked: frame.map_points.iter().map(Option::is_some).collect(),
        })
    }

    /// Every map that has been anchored in the world (a map whose frames
    /// were all lost has no place in it yet and is left out).
    pub fn map_views(&self) -> Result<Vec<MapView>, SlamError> {
        let anchors = self.map_anchors()?;
        let active = self.atlas.active().index;
        let mut views = Vec::new();
        for entry in self.atlas.maps() {
            let Some(anchor) = anchors.get(&entry.index) else {
                continue;
            };
            let map = entry.map.read().map_err(|_| SlamError::PoisonedMap)?;
            let to_world = anchor.to_isometry();
            let points = map
                .map_points()
                .map(|p| {
                    let w = to_world * nalgebra::Point3::from(p.position);
                    [w.x as f32, w.y as f32, w.z as f32]
                })
                .collect();
            let keyframes = map
                .keyframes()
                .map(|kf| KeyFrameView {
                    id: kf.id().0,
                    frame: kf.frame_index,
                    pose_wc: anchor.compose(&kf.pose_wc()),
                })
                .collect();
            views.push(MapView {
                map: entry.index,
                active: entry.index == active,
                points,
                keyframes,
            });
        }
        Ok(views)
    }
}
