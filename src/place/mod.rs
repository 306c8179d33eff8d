//! Place recognition: the layer below the system layer that finds where
//! a frame has been before (loop closing, relocalisation). It may use
//! [`features`](crate::features) and nothing above.
//!
//! It holds:
//! - [`kmeans`](kmeans::kmeans): k-means over flat descriptor rows with
//!   k-means++ seeding and a seeded generator, for either metric
//!   ([`L2Float`] for SuperPoint's float rows, [`HammingBinary`] for ORB or
//!   sign-bit rows), shared by both vocabularies below;
//! - [`VocabularyTree`]: DBoW2's hierarchical k-means vocabulary
//!   (`TemplatedVocabulary::create`) with TF-IDF word weights;
//! - [`dbow2_text`]: the DBoW2 text format that ORB-SLAM3's
//!   `TemplatedVocabulary::loadFromTextFile` reads, written atomically, and
//!   read back;
//! - [`GlobalDescriptor`]: one unit vector per keyframe, with [`Vlad`] over
//!   a k-means codebook (optionally PCA-[`Whitening`]ed) as the built-in one;
//! - [`Codebook`]: the versioned, checksummed codebook file, tied to the
//!   extractor settings it was trained for ([`extractor_settings_hash`]);
//! - [`KeyframeDatabase`]: insert, erase and a brute-force cosine query
//!   scored over covisibility groups, as ORB-SLAM3's
//!   `DetectNBestCandidates`.

pub mod codebook;
pub mod database;
pub mod dbow2_text;
mod error;
pub mod global_descriptor;
pub mod kmeans;
mod metric;
mod rng;
mod rows;
pub mod sketch;
pub mod vlad;
mod vocabulary_tree;

pub use codebook::{
    default_codebook_for, default_codebook_path, extractor_settings_hash, Codebook,
};
pub use database::{Candidate, KeyframeDatabase, QueryOptions, SHORTLIST};
pub use error::PlaceError;
pub use global_descriptor::GlobalDescriptor;
pub use kmeans::{kmeans, kmeans_subset, KMeansOptions, KMeansResult};
pub use metric::{ClusterMetric, HammingBinary, L2Float};
pub use rng::SeededRng;
pub use rows::DescriptorRows;
pub use vlad::{Vlad, Whitening, DEFAULT_K};
pub use vocabulary_tree::{
    BuildOutcome, TreeNode, TreeParams, TreeProgress, TreeStage, VocabularyTree, MAX_BRANCHING,
    MAX_DEPTH,
};
