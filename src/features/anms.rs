//! Keypoint selection: the paper's ANMS on a kd-tree, Bailo et al.'s SSC, and top-N.

/// A detection candidate: position and score.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Candidate {
    /// Column in pixels.
    pub x: f32,
    /// Row in pixels.
    pub y: f32,
    /// Detector score; higher is stronger.
    pub score: f32,
}
