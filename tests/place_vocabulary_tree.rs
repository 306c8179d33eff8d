//! The vocabulary tree (`spslam::place::VocabularyTree`): its shape, greedy
//! descent against the training clusters, TF-IDF weights against a brute
//! force count, determinism, and the limits on k and L.

use proptest::prelude::*;
use spslam::place::{
    BuildOutcome, ClusterMetric, DescriptorRows, HammingBinary, L2Float, PlaceError, SeededRng,
    TreeParams, TreeProgress, TreeStage, VocabularyTree,
};

/// `blobs` Gaussian-ish blobs of `per` rows each in `dim` dimensions, rows
/// shuffled over the blobs.
fn float_rows(blobs: usize, per: usize, dim: usize, seed: u64) -> DescriptorRows<f32> {
    let mut rng = SeededRng::new(seed);
    let centres: Vec<Vec<f32>> = (0..blobs)
        .map(|_| (0..dim).map(|_| 10.0 * rng.next_unit() as f32).collect())
        .collect();
    let mut rows = DescriptorRows::new(dim).unwrap();
    for _ in 0..blobs * per {
        let c = &centres[rng.below(blobs)];
        let row: Vec<f32> = c
            .iter()
            .map(|v| v + (rng.next_unit() as f32 - 0.5))
            .collect();
        rows.push_row(&row).unwrap();
    }
    rows
}

fn binary_rows(n: usize, seed: u64) -> DescriptorRows<u8> {
    let mut rng = SeededRng::new(seed);
    let flat: Vec<u8> = (0..n * 32).map(|_| rng.next_u64() as u8).collect();
    DescriptorRows::from_flat(32, flat).unwrap()
}

fn build<M: ClusterMetric>(
    metric: M,
    rows: &DescriptorRows<M::Elem>,
    images: &[usize],
    params: &TreeParams,
) -> BuildOutcome<M> {
    VocabularyTree::build(metric, rows, images, params, &mut |_| {}).unwrap()
}

/// Shape: node count within k^0 + ... + k^L, parents before children and
/// levels in breadth-first order, 1..=k children per internal node, leaves
/// are exactly the words (numbered in node order), internal weights 0.
fn assert_shape<M: ClusterMetric>(tree: &VocabularyTree<M>, params: &TreeParams) {
    assert!(tree.node_count() <= params.max_nodes());
    let nodes = tree.nodes();
    assert!(!nodes[0].children.is_empty());
    let mut last_level = 0;
    let mut words = Vec::new();
    for (id, node) in nodes.iter().enumerate().skip(1) {
        assert!(
            (node.parent as usize) < id,
            "node {id}'s parent comes after it"
        );
        assert!(nodes[node.parent as usize].children.contains(&(id as u32)));
        let level = tree.level(id);
        assert!(
            (1..=params.depth).contains(&level),
            "node {id} on level {level}"
        );
        assert!(level >= last_level, "node {id} breaks breadth-first order");
        last_level = level;
        assert!(node.children.len() <= params.k);
        if node.is_leaf() {
            assert_eq!(node.word, Some(words.len() as u32));
            words.push(id as u32);
        } else {
            assert_eq!(node.word, None);
            assert_eq!(node.weight, 0.0);
        }
    }
    assert_eq!(tree.words(), &words[..]);
}

/// DBoW2's IDF weights recomputed by brute force: for each word, the images
/// with a descriptor descending to it.
fn assert_weights<M: ClusterMetric>(
    tree: &VocabularyTree<M>,
    rows: &DescriptorRows<M::Elem>,
    images: &[usize],
) {
    let mut start = 0;
    let mut sets = vec![std::collections::BTreeSet::new(); tree.word_count()];
    for (image, &len) in images.iter().enumerate() {
        for r in start..start + len {
            let word = tree.word_of(rows.row(r)).unwrap() as usize;
            sets[word].insert(image);
        }
        start += len;
    }
    for (w, &node) in tree.words().iter().enumerate() {
        let expected = if sets[w].is_empty() {
            0.0
        } else {
            (images.len() as f64 / sets[w].len() as f64).ln()
        };
        assert_eq!(tree.nodes()[node as usize].weight, expected, "word {w}");
    }
}

#[test]
fn float_tree_descends_to_its_training_clusters_and_weights_by_idf() {
    let rows = float_rows(20, 30, 16, 1);
    let images = vec![50; 12];
    let params = TreeParams::new(3, 4);
    let outcome = build(L2Float { dim: 16 }, &rows, &images, &params);
    let tree = &outcome.tree;
    assert_shape(tree, &params);
    assert!(outcome.kmeans_runs > 0);
    assert!(tree.word_count() > 20 && tree.word_count() <= rows.len());
    for r in 0..rows.len() {
        let leaf = tree.descend(rows.row(r)).unwrap();
        assert_eq!(leaf, outcome.training_leaves[r], "row {r}");
        assert!(tree.nodes()[leaf as usize].is_leaf());
    }
    // With L2 every centre lies in its ancestors' Voronoi cells (a mean of
    // points inside a convex cell), so greedy descent from a word's own
    // centre finds that word: checked against every word by brute force.
    for (w, &node) in tree.words().iter().enumerate() {
        let centre = tree.descriptor(node as usize).to_vec();
        assert_eq!(tree.word_of(&centre), Some(w as u32), "word {w}");
    }
    assert_weights(tree, &rows, &images);
}

#[test]
fn binary_tree_descends_to_its_training_clusters_and_weights_by_idf() {
    let rows = binary_rows(400, 2);
    let images = vec![40, 0, 60, 100, 200];
    let params = TreeParams::new(4, 3);
    let outcome = build(HammingBinary { bytes: 32 }, &rows, &images, &params);
    assert_shape(&outcome.tree, &params);
    for r in 0..rows.len() {
        assert_eq!(
            outcome.tree.descend(rows.row(r)),
            Some(outcome.training_leaves[r]),
            "row {r}"
        );
    }
    assert_weights(&outcome.tree, &rows, &images);
    // Word weights are ln(N / n_i) with N = 5 images (the empty one counts).
    let max = outcome
        .tree
        .nodes()
        .iter()
        .map(|n| n.weight)
        .fold(0.0, f64::max);
    assert!((max - 5f64.ln()).abs() < 1e-12);
}

#[test]
fn at_most_k_descriptors_become_one_child_each() {
    let rows = float_rows(5, 1, 4, 3);
    let outcome = build(L2Float { dim: 4 }, &rows, &[5], &TreeParams::new(10, 6));
    let tree = &outcome.tree;
    assert_eq!(tree.node_count(), 6);
    assert_eq!(tree.word_count(), 5);
    for i in 0..5 {
        assert_eq!(tree.descriptor(i + 1), rows.row(i));
        // One image holding every word: ln(1/1) = 0.
        assert_eq!(tree.nodes()[i + 1].weight, 0.0);
    }
}

#[test]
fn the_same_seed_gives_the_same_tree() {
    let rows = float_rows(10, 20, 8, 4);
    let images = [100, 100];
    let mut params = TreeParams::new(4, 3);
    let a = build(L2Float { dim: 8 }, &rows, &images, &params).tree;
    let b = build(L2Float { dim: 8 }, &rows, &images, &params).tree;
    assert_eq!(a.nodes(), b.nodes());
    assert_eq!(a.descriptors(), b.descriptors());
    params.seed = 99;
    let c = build(L2Float { dim: 8 }, &rows, &images, &params).tree;
    assert_ne!(a.descriptors(), c.descriptors());
}

#[test]
fn progress_covers_every_level_and_the_weights() {
    let rows = float_rows(10, 20, 8, 5);
    let mut reports: Vec<TreeProgress> = Vec::new();
    VocabularyTree::build(
        L2Float { dim: 8 },
        &rows,
        &[200],
        &TreeParams::new(3, 2),
        &mut |p| reports.push(p),
    )
    .unwrap();
    for stage in [TreeStage::Level(1), TreeStage::Level(2), TreeStage::Weights] {
        let last = reports.iter().rfind(|p| p.stage == stage).unwrap();
        assert_eq!(last.done, last.total, "{stage:?}");
    }
    assert_eq!(reports.last().unwrap().total, 200);
}

#[test]
fn out_of_range_parameters_and_bad_input_are_typed_errors() {
    let rows = float_rows(2, 5, 4, 6);
    let metric = L2Float { dim: 4 };
    for (k, depth) in [(21, 6), (1, 6), (10, 11), (10, 0)] {
        let err = VocabularyTree::build(
            metric,
            &rows,
            &[10],
            &TreeParams::new(k, depth),
            &mut |_| {},
        )
        .unwrap_err();
        assert!(matches!(err, PlaceError::InvalidParameter { .. }), "{err}");
        assert!(err.to_string().contains("ORB-SLAM3"), "{err}");
    }
    let err = VocabularyTree::build(metric, &rows, &[3], &TreeParams::new(10, 6), &mut |_| {})
        .unwrap_err();
    assert!(matches!(err, PlaceError::Inconsistent { .. }), "{err}");
    let empty = DescriptorRows::<f32>::new(4).unwrap();
    let err = VocabularyTree::build(
        metric,
        &empty,
        &[0, 0],
        &TreeParams::new(10, 6),
        &mut |_| {},
    )
    .unwrap_err();
    assert!(matches!(err, PlaceError::NoDescriptors { .. }), "{err}");
    let err = VocabularyTree::build(
        L2Float { dim: 5 },
        &rows,
        &[10],
        &TreeParams::new(10, 6),
        &mut |_| {},
    )
    .unwrap_err();
    assert!(matches!(err, PlaceError::RowLength { .. }), "{err}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Any small float data set, k and L: the shape holds, every row
    /// descends to the leaf it was clustered into, and the weights are
    /// DBoW2's.
    #[test]
    fn any_small_tree_keeps_its_invariants(
        n in 1usize..80,
        k in 2usize..6,
        depth in 1usize..5,
        seed in any::<u64>(),
    ) {
        // Distinct rows (a duplicate would descend to its first copy).
        let rows = float_rows(4, n.div_ceil(4), 3, seed);
        let images: Vec<usize> = (0..rows.len()).map(|_| 1).collect();
        let params = TreeParams { seed, ..TreeParams::new(k, depth) };
        let outcome = build(L2Float { dim: 3 }, &rows, &images, &params);
        assert_shape(&outcome.tree, &params);
        for r in 0..rows.len() {
            prop_assert_eq!(outcome.tree.descend(rows.row(r)), Some(outcome.training_leaves[r]));
        }
        assert_weights(&outcome.tree, &rows, &images);
    }
}
