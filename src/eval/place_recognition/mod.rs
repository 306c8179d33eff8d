//! Place-recognition evaluation: which image pairs truly show the same
//! place ([`view_overlap`], from ground-truth poses and depth), and the
//! precision–recall of an acceptance rule over verified candidates
//! ([`precision_recall`]). Independent of the SLAM core.

pub mod precision_recall;
pub mod view_overlap;

pub use precision_recall::{
    lowest_exact_threshold, precision_recall, CandidateTruth, PrPoint, RevisitTruth,
    ScoredCandidate,
};
pub use view_overlap::{view_overlap, OverlapCamera, SceneDepth};
