//! ORB-SLAM3's ORB extractor, for the baseline: image pyramid, FAST on
//! ~35-px cells with the fallback threshold, the octree (quadtree)
//! distribution that keeps the strongest keypoint per node, intensity-centroid
//! orientation and rBRIEF descriptors on the blurred level.

mod config;
mod describe;
mod extractor;
mod fast_cells;
pub mod octree;

pub use config::OrbConfig;
pub use extractor::OrbExtractor;
pub use fast_cells::{detect_fast_in_cells, FastCorner, EDGE_THRESHOLD};
