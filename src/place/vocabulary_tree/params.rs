//! The shape of a vocabulary tree and the progress reports of its training.

use crate::place::kmeans::DEFAULT_MAX_ITERATIONS;
use crate::place::PlaceError;

/// The largest branching factor ORB-SLAM3's text loader accepts.
pub const MAX_BRANCHING: usize = 20;
/// The largest depth ORB-SLAM3's text loader accepts.
pub const MAX_DEPTH: usize = 10;

/// The tree's shape and how it is trained.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TreeParams {
    /// Branching factor k: 2..=[`MAX_BRANCHING`].
    pub k: usize,
    /// Depth L (levels below the root): 1..=[`MAX_DEPTH`].
    pub depth: usize,
    /// k-means rounds per node, at most (see [`KMeansOptions`](crate::place::KMeansOptions)).
    pub max_iterations: usize,
    /// Seed of the k-means++ draws: the same seed and data give the same tree.
    pub seed: u64,
}

impl TreeParams {
    /// k and L with [`DEFAULT_MAX_ITERATIONS`] and seed 0.
    pub fn new(k: usize, depth: usize) -> Self {
        Self {
            k,
            depth,
            max_iterations: DEFAULT_MAX_ITERATIONS,
            seed: 0,
        }
    }

    /// Checks k and L against the limits of ORB-SLAM3's text loader
    /// (`0 <= k <= 20`, `1 <= L <= 10`; k < 2 gives no tree).
    pub fn validate(&self) -> Result<(), PlaceError> {
        if !(2..=MAX_BRANCHING).contains(&self.k) {
            return Err(PlaceError::invalid(
                "k (branching factor)",
                self.k,
                "between 2 and 20 (ORB-SLAM3's loader rejects k > 20)",
            ));
        }
        if !(1..=MAX_DEPTH).contains(&self.depth) {
            return Err(PlaceError::invalid(
                "L (depth)",
                self.depth,
                "between 1 and 10 (ORB-SLAM3's loader rejects L > 10)",
            ));
        }
        Ok(())
    }

    /// The most nodes a tree of this shape can have, root included:
    /// `(k^(L+1) - 1) / (k - 1)` (saturating).
    pub fn max_nodes(&self) -> usize {
        let mut total = 1usize;
        let mut level = 1usize;
        for _ in 0..self.depth {
            level = level.saturating_mul(self.k);
            total = total.saturating_add(level);
        }
        total
    }
}

/// Which part of the training a [`TreeProgress`] report is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TreeStage {
    /// Splitting the nodes of a level (1-based) into their children.
    Level(usize),
    /// Descending every training descriptor to count the images per word.
    Weights,
}

/// Progress of [`VocabularyTree::build`](super::VocabularyTree::build), reported after each node split
/// and each image weighed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TreeProgress {
    /// What is being done.
    pub stage: TreeStage,
    /// Descriptors handled so far in this stage.
    pub done: usize,
    /// Descriptors this stage handles in all.
    pub total: usize,
}
