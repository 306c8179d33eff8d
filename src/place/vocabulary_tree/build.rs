//! Training a vocabulary tree: DBoW2's `HKmeansStep`, level by level, then
//! `setNodeWeights`.

use super::{root, TreeNode, TreeParams, TreeProgress, TreeStage, VocabularyTree};
use crate::place::kmeans::{kmeans_subset, KMeansOptions};
use crate::place::{ClusterMetric, DescriptorRows, PlaceError, SeededRng};

/// A vocabulary tree and what the training saw.
#[derive(Debug, Clone)]
pub struct BuildOutcome<M: ClusterMetric> {
    /// The tree.
    pub tree: VocabularyTree<M>,
    /// For each training descriptor, the leaf (node id) it was clustered
    /// into. Greedy descent from the root reaches this leaf too, except for
    /// a descriptor equal to an earlier sibling's.
    pub training_leaves: Vec<u32>,
    /// Nodes split by k-means (the others had at most k descriptors).
    pub kmeans_runs: usize,
    /// k-means runs stopped by the iteration cap rather than by convergence.
    pub kmeans_capped: usize,
}

impl<M: ClusterMetric> VocabularyTree<M> {
    /// Trains a tree on `rows`, the descriptors of the training images one
    /// image after the other; `image_lengths[i]` is image `i`'s number of
    /// rows (images without descriptors still count in N).
    pub fn build(
        metric: M,
        rows: &DescriptorRows<M::Elem>,
        image_lengths: &[usize],
        params: &TreeParams,
        progress: &mut dyn FnMut(TreeProgress),
    ) -> Result<BuildOutcome<M>, PlaceError> {
        params.validate()?;
        if metric.row_len() != rows.row_len() {
            return Err(PlaceError::RowLength {
                expected: metric.row_len(),
                actual: rows.row_len(),
            });
        }
        if image_lengths.iter().sum::<usize>() != rows.len() {
            return Err(PlaceError::Inconsistent {
                reason: format!(
                    "the images' descriptor counts add up to {}, but there are {} rows",
                    image_lengths.iter().sum::<usize>(),
                    rows.len()
                ),
            });
        }
        if rows.is_empty() {
            return Err(PlaceError::NoDescriptors {
                reason: format!("the {} training images gave none", image_lengths.len()),
            });
        }
        let n = u32::try_from(rows.len()).map_err(|_| {
            PlaceError::invalid("number of descriptors", rows.len(), "at most 4294967295")
        })?;
        let mut builder = Builder {
            tree: VocabularyTree {
                metric,
                k: params.k,
                depth: params.depth,
                nodes: vec![root()],
                descriptors: DescriptorRows::new(rows.row_len())?,
                words: Vec::new(),
            },
            training_leaves: vec![0; rows.len()],
            rng: SeededRng::new(params.seed),
            options: KMeansOptions {
                k: params.k,
                max_iterations: params.max_iterations,
            },
            kmeans_runs: 0,
            kmeans_capped: 0,
        };
        builder
            .tree
            .descriptors
            .push_row(&vec![M::Elem::default(); rows.row_len()])?;
        let mut frontier: Vec<(u32, Vec<u32>)> = vec![(0, (0..n).collect())];
        for level in 1..=params.depth {
            frontier = builder.split_level(rows, level, frontier, progress)?;
            if frontier.is_empty() {
                break;
            }
        }
        let mut outcome = BuildOutcome {
            tree: builder.tree,
            training_leaves: builder.training_leaves,
            kmeans_runs: builder.kmeans_runs,
            kmeans_capped: builder.kmeans_capped,
        };
        outcome.tree.number_words();
        outcome.tree.set_weights(rows, image_lengths, progress);
        Ok(outcome)
    }

    /// DBoW2's `setNodeWeights` for TF-IDF: `ln(N / n_i)` per word.
    fn set_weights(
        &mut self,
        rows: &DescriptorRows<M::Elem>,
        image_lengths: &[usize],
        progress: &mut dyn FnMut(TreeProgress),
    ) {
        let mut images_with = vec![0u32; self.words.len()];
        // The last image (1-based) that counted each word.
        let mut counted_in = vec![0usize; self.words.len()];
        let mut start = 0;
        for (image, &len) in image_lengths.iter().enumerate() {
            for r in start..start + len {
                if let Some(word) = self.word_of(rows.row(r)) {
                    let w = word as usize;
                    if counted_in[w] != image + 1 {
                        counted_in[w] = image + 1;
                        images_with[w] += 1;
                    }
                }
            }
            start += len;
            progress(TreeProgress {
                stage: TreeStage::Weights,
                done: start,
                total: rows.len(),
            });
        }
        let n_images = image_lengths.len() as f64;
        for (w, &node) in self.words.iter().enumerate() {
            self.nodes[node as usize].weight = if images_with[w] > 0 {
                (n_images / f64::from(images_with[w])).ln()
            } else {
                0.0
            };
        }
    }
}

/// The state of one training run.
struct Builder<M: ClusterMetric> {
    tree: VocabularyTree<M>,
    training_leaves: Vec<u32>,
    rng: SeededRng,
    options: KMeansOptions,
    kmeans_runs: usize,
    kmeans_capped: usize,
}

impl<M: ClusterMetric> Builder<M> {
    /// Splits each node of `frontier` (node id, its rows) into children on
    /// `level`; returns the children to split on the next level.
    fn split_level(
        &mut self,
        rows: &DescriptorRows<M::Elem>,
        level: usize,
        frontier: Vec<(u32, Vec<u32>)>,
        progress: &mut dyn FnMut(TreeProgress),
    ) -> Result<Vec<(u32, Vec<u32>)>, PlaceError> {
        let total: usize = frontier.iter().map(|(_, m)| m.len()).sum();
        let mut done = 0;
        let mut next = Vec::new();
        for (parent, members) in frontier {
            done += members.len();
            for (child, group) in self.split_node(rows, parent, members)? {
                for &r in &group {
                    self.training_leaves[r as usize] = child;
                }
                if level < self.tree.depth && group.len() > 1 {
                    next.push((child, group));
                }
            }
            progress(TreeProgress {
                stage: TreeStage::Level(level),
                done,
                total,
            });
        }
        Ok(next)
    }

    /// One `HKmeansStep` without the recursion: the children of `parent`
    /// and the rows of each.
    fn split_node(
        &mut self,
        rows: &DescriptorRows<M::Elem>,
        parent: u32,
        members: Vec<u32>,
    ) -> Result<Vec<(u32, Vec<u32>)>, PlaceError> {
        let (centres, groups) = if members.len() <= self.tree.k {
            // DBoW2's trivial case: one child per descriptor.
            let mut centres = DescriptorRows::new(rows.row_len())?;
            for &m in &members {
                centres.push_row(rows.row(m as usize))?;
            }
            let groups = members.iter().map(|&m| vec![m]).collect();
            (centres, groups)
        } else {
            let result = kmeans_subset(
                &self.tree.metric,
                rows,
                &members,
                &self.options,
                &mut self.rng,
            )?;
            self.kmeans_runs += 1;
            if !result.converged {
                self.kmeans_capped += 1;
            }
            let groups = result.groups(&members);
            (result.centres, groups)
        };
        let mut children = Vec::with_capacity(groups.len());
        for (c, group) in groups.into_iter().enumerate() {
            let id = u32::try_from(self.tree.nodes.len()).map_err(|_| {
                PlaceError::invalid("number of nodes", self.tree.nodes.len(), "at most 2^32 - 1")
            })?;
            self.tree.nodes.push(TreeNode {
                parent,
                children: Vec::new(),
                weight: 0.0,
                word: None,
            });
            self.tree.descriptors.push_row(centres.row(c))?;
            self.tree.nodes[parent as usize].children.push(id);
            children.push((id, group));
        }
        Ok(children)
    }
}
