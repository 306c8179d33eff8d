//! DBoW2's vocabulary tree (`TemplatedVocabulary`): hierarchical k-means
//! with branching factor k and depth L, whose leaves are the words, each
//! weighted by its inverse document frequency (TF-IDF weighting).
//!
//! Building follows `TemplatedVocabulary::create` and `HKmeansStep`:
//! - the root holds every training descriptor;
//! - a node with at most k descriptors gets one child per descriptor (the
//!   descriptor is the child's centre); a node with more is split by
//!   [`kmeans_subset`](crate::place::kmeans_subset) into at most k children;
//! - a child is split again when it is above depth L and holds more than one
//!   descriptor; otherwise it is a leaf (a word);
//! - a word's weight is `ln(N / n_i)`, N the number of training images and
//!   `n_i` the number of them with at least one descriptor that descends to
//!   the word (DBoW2's `setNodeWeights`, descent as in `transform`); a word
//!   no training descriptor reaches keeps weight 0, as do internal nodes.
//!
//! One difference in order: DBoW2 numbers the nodes as its recursion creates
//! them (depth first); here they are numbered breadth first (the root 0,
//! then level 1, level 2, ...), so parents always come before their
//! children, as the text format needs. Words are numbered in node order, as
//! DBoW2's `createWords` and ORB-SLAM3's loader number them.

mod build;
mod params;

pub use build::BuildOutcome;
pub use params::{TreeParams, TreeProgress, TreeStage, MAX_BRANCHING, MAX_DEPTH};

use super::{ClusterMetric, DescriptorRows};

/// One node of the tree.
#[derive(Debug, Clone, PartialEq)]
pub struct TreeNode {
    /// The parent's id (the root's is 0).
    pub parent: u32,
    /// Children's ids, in the order their clusters were made.
    pub children: Vec<u32>,
    /// The word's IDF weight for a leaf; 0 for internal nodes.
    pub weight: f64,
    /// The word id of a leaf; `None` for the root and internal nodes.
    pub word: Option<u32>,
}

impl TreeNode {
    /// True for a word (a node without children, other than the root).
    pub fn is_leaf(&self) -> bool {
        self.children.is_empty()
    }
}

/// A DBoW2 vocabulary: nodes in breadth-first order (root 0), one
/// descriptor row per node (the root's is all zeros), the leaves as words.
#[derive(Debug, Clone)]
pub struct VocabularyTree<M: ClusterMetric> {
    metric: M,
    k: usize,
    depth: usize,
    nodes: Vec<TreeNode>,
    descriptors: DescriptorRows<M::Elem>,
    words: Vec<u32>,
}

impl<M: ClusterMetric> VocabularyTree<M> {
    /// A tree from its parts, as read from a file: `nodes[0]` is the root,
    /// `descriptors` holds one row per node, parents come before children.
    /// Words are numbered in node order; the nodes' `word` fields are set
    /// accordingly.
    pub(crate) fn from_parts(
        metric: M,
        k: usize,
        depth: usize,
        mut nodes: Vec<TreeNode>,
        descriptors: DescriptorRows<M::Elem>,
    ) -> Self {
        for node in &mut nodes {
            node.word = None;
        }
        let mut tree = Self {
            metric,
            k,
            depth,
            nodes,
            descriptors,
            words: Vec::new(),
        };
        tree.number_words();
        tree
    }

    /// The metric the tree was trained with.
    pub fn metric(&self) -> &M {
        &self.metric
    }

    /// Branching factor k.
    pub fn k(&self) -> usize {
        self.k
    }

    /// Depth L.
    pub fn depth(&self) -> usize {
        self.depth
    }

    /// All nodes, the root first.
    pub fn nodes(&self) -> &[TreeNode] {
        &self.nodes
    }

    /// Node `id`'s descriptor (the root's is all zeros). Panics when out of range.
    pub fn descriptor(&self, id: usize) -> &[M::Elem] {
        self.descriptors.row(id)
    }

    /// Every node's descriptor, one row per node.
    pub fn descriptors(&self) -> &DescriptorRows<M::Elem> {
        &self.descriptors
    }

    /// Number of nodes, the root included.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Number of words (leaves).
    pub fn word_count(&self) -> usize {
        self.words.len()
    }

    /// The node id of each word.
    pub fn words(&self) -> &[u32] {
        &self.words
    }

    /// The level of node `id` (root 0, its children 1, ...).
    pub fn level(&self, id: usize) -> usize {
        let mut level = 0;
        let mut node = id;
        while node != 0 {
            node = self.nodes[node].parent as usize;
            level += 1;
        }
        level
    }

    /// DBoW2's `transform`: from the root, go to the nearest child (the
    /// first among equals) until a leaf; returns that leaf's node id, or
    /// `None` for a tree without words.
    pub fn descend(&self, row: &[M::Elem]) -> Option<u32> {
        let mut node = 0usize;
        loop {
            let children = &self.nodes[node].children;
            let (&first, rest) = children.split_first()?;
            let mut best = first;
            let mut best_d = self
                .metric
                .distance(row, self.descriptors.row(first as usize));
            for &c in rest {
                let d = self.metric.distance(row, self.descriptors.row(c as usize));
                if d < best_d {
                    best_d = d;
                    best = c;
                }
            }
            node = best as usize;
            if self.nodes[node].is_leaf() {
                return Some(best);
            }
        }
    }

    /// The word a row descends to (see [`descend`](Self::descend)).
    pub fn word_of(&self, row: &[M::Elem]) -> Option<u32> {
        self.descend(row)
            .and_then(|node| self.nodes[node as usize].word)
    }

    fn number_words(&mut self) {
        self.words.clear();
        for (id, node) in self.nodes.iter_mut().enumerate().skip(1) {
            if node.is_leaf() {
                node.word = Some(self.words.len() as u32);
                self.words.push(id as u32);
            }
        }
    }
}

fn root() -> TreeNode {
    TreeNode {
        parent: 0,
        children: Vec::new(),
        weight: 0.0,
        word: None,
    }
}
