//! Identifiers of keyframes and map points: plain numbers, never pointers.

use serde::{Deserialize, Serialize};

/// A keyframe's identifier, unique within a map and increasing with creation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct KeyFrameId(pub u64);

/// A map point's identifier, unique within a map and increasing with creation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct MapPointId(pub u64);

impl std::fmt::Display for KeyFrameId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "keyframe {}", self.0)
    }
}

impl std::fmt::Display for MapPointId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "map point {}", self.0)
    }
}
