//! Place recognition: the layer below the system layer that will find where
//! a frame has been before (loop closing, relocalisation). It may use
//! [`features`](crate::features) and nothing above.
//!
//! Today it holds what a bag-of-words place recogniser is trained with:
//! - [`kmeans`](kmeans::kmeans): k-means over flat descriptor rows with
//!   k-means++ seeding and a seeded generator, for either metric
//!   ([`L2Float`] for SuperPoint's float rows, [`HammingBinary`] for ORB or
//!   sign-bit rows); a VLAD codebook will share it;
//! - [`VocabularyTree`]: DBoW2's hierarchical k-means vocabulary
//!   (`TemplatedVocabulary::create`) with TF-IDF word weights;
//! - [`dbow2_text`]: the DBoW2 text format that ORB-SLAM3's
//!   `TemplatedVocabulary::loadFromTextFile` reads, written atomically, and
//!   read back.

pub mod dbow2_text;
mod error;
pub mod kmeans;
mod metric;
mod rng;
mod rows;
mod vocabulary_tree;

pub use error::PlaceError;
pub use kmeans::{kmeans, kmeans_subset, KMeansOptions, KMeansResult};
pub use metric::{ClusterMetric, HammingBinary, L2Float};
pub use rng::SeededRng;
pub use rows::DescriptorRows;
pub use vocabulary_tree::{
    BuildOutcome, TreeNode, TreeParams, TreeProgress, TreeStage, VocabularyTree, MAX_BRANCHING,
    MAX_DEPTH,
};
