//! k-means over descriptor rows, as DBoW2 runs it in each node of its
//! vocabulary tree (`HKmeansStep`): k-means++ seeding
//! (`initiateClustersKMpp`), then Lloyd iterations until no row changes
//! cluster, here capped at [`KMeansOptions::max_iterations`].
//!
//! Deterministic: the seeding draws from a [`SeededRng`], and ties go to the
//! lowest cluster index, as in DBoW2's strict `<` comparison.

use super::{ClusterMetric, DescriptorRows, PlaceError, SeededRng};

/// The iteration cap used by default. DBoW2 iterates until no assignment
/// changes, without a cap; 20 rounds leave, on a large node, at most a few
/// rows moving between clusters and bound the training time.
pub const DEFAULT_MAX_ITERATIONS: usize = 20;

/// How many clusters, and how long to iterate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct KMeansOptions {
    /// Clusters wanted (> 0). Fewer come back when the rows hold fewer
    /// distinct values (k-means++ stops when every row is on a centre).
    pub k: usize,
    /// Update-and-reassign rounds after the first assignment, at most.
    pub max_iterations: usize,
}

impl KMeansOptions {
    /// `k` clusters with [`DEFAULT_MAX_ITERATIONS`].
    pub fn new(k: usize) -> Self {
        Self {
            k,
            max_iterations: DEFAULT_MAX_ITERATIONS,
        }
    }
}

/// The clusters found.
#[derive(Debug, Clone, PartialEq)]
pub struct KMeansResult<T> {
    /// One centre per cluster (at most `k`). A cluster that lost all its
    /// members keeps the centre it had.
    pub centres: DescriptorRows<T>,
    /// For each member row, in the order given, the index of its cluster:
    /// its nearest centre (the lowest index among equals).
    pub assignment: Vec<u32>,
    /// Update-and-reassign rounds run.
    pub iterations: usize,
    /// True when the last round changed no assignment (false: stopped by the cap).
    pub converged: bool,
}

impl<T: Copy> KMeansResult<T> {
    /// The member rows of each cluster, as indices into the rows clustered,
    /// given the `members` passed to [`kmeans_subset`] (for [`kmeans`]:
    /// `0..n`).
    pub fn groups(&self, members: &[u32]) -> Vec<Vec<u32>> {
        groups_of(&self.assignment, members, self.centres.len())
    }
}

/// Clusters every row of `rows` into at most `options.k` clusters.
pub fn kmeans<M: ClusterMetric>(
    metric: &M,
    rows: &DescriptorRows<M::Elem>,
    options: &KMeansOptions,
    rng: &mut SeededRng,
) -> Result<KMeansResult<M::Elem>, PlaceError> {
    let n = u32::try_from(rows.len()).map_err(|_| {
        PlaceError::invalid("number of rows", rows.len(), "at most 4294967295 rows")
    })?;
    let members: Vec<u32> = (0..n).collect();
    kmeans_subset(metric, rows, &members, options, rng)
}

/// Clusters the rows `members` of `rows` (indices, in any order) into at most
/// `options.k` clusters; the assignment follows the order of `members`.
pub fn kmeans_subset<M: ClusterMetric>(
    metric: &M,
    rows: &DescriptorRows<M::Elem>,
    members: &[u32],
    options: &KMeansOptions,
    rng: &mut SeededRng,
) -> Result<KMeansResult<M::Elem>, PlaceError> {
    if options.k == 0 {
        return Err(PlaceError::invalid("k", 0, "at least one cluster"));
    }
    if metric.row_len() != rows.row_len() {
        return Err(PlaceError::RowLength {
            expected: metric.row_len(),
            actual: rows.row_len(),
        });
    }
    if members.is_empty() {
        return Err(PlaceError::NoDescriptors {
            reason: "k-means was given no rows".into(),
        });
    }
    if let Some(&bad) = members.iter().find(|&&m| m as usize >= rows.len()) {
        return Err(PlaceError::Inconsistent {
            reason: format!("member row {bad} is past the {} rows", rows.len()),
        });
    }
    let mut centres = seed_kmeans_pp(metric, rows, members, options.k, rng)?;
    let mut assignment = vec![0u32; members.len()];
    assign(metric, rows, members, &centres, &mut assignment);
    let mut next = assignment.clone();
    let mut iterations = 0;
    let mut converged = false;
    while iterations < options.max_iterations {
        update_centres(metric, rows, members, &assignment, &mut centres);
        assign(metric, rows, members, &centres, &mut next);
        iterations += 1;
        if next == assignment {
            converged = true;
            break;
        }
        std::mem::swap(&mut assignment, &mut next);
    }
    Ok(KMeansResult {
        centres,
        assignment,
        iterations,
        converged,
    })
}

/// DBoW2's `initiateClustersKMpp`: the first centre uniformly among the
/// members, each next one with probability proportional to its distance to
/// the nearest centre so far (for [`L2Float`](super::L2Float) a squared
/// distance: the usual D² weighting); stops early when every member lies on
/// a centre.
fn seed_kmeans_pp<M: ClusterMetric>(
    metric: &M,
    rows: &DescriptorRows<M::Elem>,
    members: &[u32],
    k: usize,
    rng: &mut SeededRng,
) -> Result<DescriptorRows<M::Elem>, PlaceError> {
    let row = |i: usize| rows.row(members[i] as usize);
    let mut centres = DescriptorRows::new(rows.row_len())?;
    let first = rng.below(members.len());
    centres.push_row(row(first))?;
    let mut min_dist: Vec<f64> = (0..members.len())
        .map(|i| f64::from(metric.distance(row(i), row(first))))
        .collect();
    while centres.len() < k {
        let total: f64 = min_dist.iter().sum();
        if total <= 0.0 {
            break;
        }
        // A cut in (0, total]: the first member whose running sum reaches it.
        let cut = total * (1.0 - rng.next_unit());
        let mut running = 0.0;
        let mut chosen = members.len() - 1;
        for (i, d) in min_dist.iter().enumerate() {
            running += d;
            if running >= cut {
                chosen = i;
                break;
            }
        }
        centres.push_row(row(chosen))?;
        let newest = centres.row(centres.len() - 1);
        for (i, d) in min_dist.iter_mut().enumerate() {
            if *d > 0.0 {
                *d = d.min(f64::from(metric.distance(row(i), newest)));
            }
        }
    }
    Ok(centres)
}

/// Each member's nearest centre; the first of equals wins.
fn assign<M: ClusterMetric>(
    metric: &M,
    rows: &DescriptorRows<M::Elem>,
    members: &[u32],
    centres: &DescriptorRows<M::Elem>,
    out: &mut [u32],
) {
    for (slot, &m) in out.iter_mut().zip(members) {
        *slot = nearest(metric, rows.row(m as usize), centres) as u32;
    }
}

/// The index of the centre nearest to `row` (the lowest among equals).
fn nearest<M: ClusterMetric>(
    metric: &M,
    row: &[M::Elem],
    centres: &DescriptorRows<M::Elem>,
) -> usize {
    let mut best = 0;
    let mut best_d = f32::INFINITY;
    for (c, centre) in centres.iter().enumerate() {
        let d = metric.distance(row, centre);
        if d < best_d {
            best_d = d;
            best = c;
        }
    }
    best
}

/// Each centre becomes the mean of its members; a cluster without members
/// keeps its centre (DBoW2 would leave an empty descriptor there).
fn update_centres<M: ClusterMetric>(
    metric: &M,
    rows: &DescriptorRows<M::Elem>,
    members: &[u32],
    assignment: &[u32],
    centres: &mut DescriptorRows<M::Elem>,
) {
    for (c, group) in groups_of(assignment, members, centres.len())
        .iter()
        .enumerate()
    {
        if !group.is_empty() {
            metric.mean(rows, group, centres.row_mut(c));
        }
    }
}

fn groups_of(assignment: &[u32], members: &[u32], clusters: usize) -> Vec<Vec<u32>> {
    let mut groups = vec![Vec::new(); clusters];
    for (&c, &m) in assignment.iter().zip(members) {
        groups[c as usize].push(m);
    }
    groups
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::place::{HammingBinary, L2Float};

    /// `clusters` blobs of `per` rows around far-apart centres, interleaved
    /// (row `i` belongs to blob `i % clusters`).
    fn float_blobs(clusters: usize, per: usize, dim: usize, seed: u64) -> DescriptorRows<f32> {
        let mut rng = SeededRng::new(seed);
        let centres: Vec<Vec<f32>> = (0..clusters)
            .map(|_| (0..dim).map(|_| 20.0 * rng.next_unit() as f32).collect())
            .collect();
        let mut rows = DescriptorRows::new(dim).unwrap();
        for i in 0..clusters * per {
            let row: Vec<f32> = centres[i % clusters]
                .iter()
                .map(|c| c + 0.3 * (rng.next_unit() as f32 - 0.5))
                .collect();
            rows.push_row(&row).unwrap();
        }
        rows
    }

    fn binary_blobs(clusters: usize, per: usize, seed: u64) -> DescriptorRows<u8> {
        let mut rng = SeededRng::new(seed);
        let prototypes: Vec<Vec<u8>> = (0..clusters)
            .map(|_| (0..32).map(|_| rng.next_u64() as u8).collect())
            .collect();
        let mut rows = DescriptorRows::new(32).unwrap();
        for i in 0..clusters * per {
            let mut row = prototypes[i % clusters].clone();
            for _ in 0..3 {
                let bit = rng.below(256);
                row[bit / 8] ^= 1 << (bit % 8);
            }
            rows.push_row(&row).unwrap();
        }
        rows
    }

    /// Every blob lands in one cluster of its own.
    fn assert_recovers(assignment: &[u32], clusters: usize) {
        let label_of_blob: Vec<u32> = (0..clusters).map(|b| assignment[b]).collect();
        for (i, &a) in assignment.iter().enumerate() {
            assert_eq!(a, label_of_blob[i % clusters], "row {i}");
        }
        let mut distinct = label_of_blob.clone();
        distinct.sort_unstable();
        distinct.dedup();
        assert_eq!(distinct.len(), clusters, "two blobs share a cluster");
    }

    #[test]
    fn recovers_well_separated_float_clusters() {
        for seed in 0..5 {
            let rows = float_blobs(5, 40, 16, 100 + seed);
            let metric = L2Float { dim: 16 };
            let result = kmeans(
                &metric,
                &rows,
                &KMeansOptions::new(5),
                &mut SeededRng::new(seed),
            )
            .unwrap();
            assert!(result.converged);
            assert_eq!(result.centres.len(), 5);
            assert_recovers(&result.assignment, 5);
            // Each centre is its blob's mean, within the noise.
            for (c, group) in result
                .groups(&(0..200).collect::<Vec<_>>())
                .iter()
                .enumerate()
            {
                let mut mean = vec![0.0f32; 16];
                metric.mean(&rows, group, &mut mean);
                assert_eq!(result.centres.row(c), &mean[..]);
            }
        }
    }

    #[test]
    fn recovers_well_separated_binary_clusters() {
        for seed in 0..5 {
            let rows = binary_blobs(4, 30, 200 + seed);
            let result = kmeans(
                &HammingBinary { bytes: 32 },
                &rows,
                &KMeansOptions::new(4),
                &mut SeededRng::new(seed),
            )
            .unwrap();
            assert!(result.converged);
            assert_recovers(&result.assignment, 4);
        }
    }

    #[test]
    fn same_seed_same_clusters_and_assignments_are_nearest_centres() {
        let rows = float_blobs(3, 50, 8, 9);
        let metric = L2Float { dim: 8 };
        let options = KMeansOptions {
            k: 7,
            max_iterations: 3,
        };
        let a = kmeans(&metric, &rows, &options, &mut SeededRng::new(1)).unwrap();
        let b = kmeans(&metric, &rows, &options, &mut SeededRng::new(1)).unwrap();
        assert_eq!(a, b);
        assert!(a.iterations <= 3);
        for (i, &c) in a.assignment.iter().enumerate() {
            assert_eq!(nearest(&metric, rows.row(i), &a.centres), c as usize);
        }
    }

    #[test]
    fn a_subset_is_clustered_in_its_own_order() {
        let rows = float_blobs(2, 20, 4, 3);
        let members: Vec<u32> = (0..40).filter(|i| i % 3 != 0).rev().collect();
        let result = kmeans_subset(
            &L2Float { dim: 4 },
            &rows,
            &members,
            &KMeansOptions::new(2),
            &mut SeededRng::new(0),
        )
        .unwrap();
        assert_eq!(result.assignment.len(), members.len());
        for (j, &m) in members.iter().enumerate() {
            let same_blob = members.iter().position(|&o| o % 2 == m % 2).unwrap();
            assert_eq!(result.assignment[j], result.assignment[same_blob]);
        }
    }

    #[test]
    fn duplicates_give_fewer_centres_and_bad_input_is_an_error() {
        let rows = DescriptorRows::from_flat(2, vec![1.0f32, 1.0, 1.0, 1.0, 3.0, 3.0]).unwrap();
        let metric = L2Float { dim: 2 };
        let result = kmeans(
            &metric,
            &rows,
            &KMeansOptions::new(5),
            &mut SeededRng::new(0),
        )
        .unwrap();
        assert_eq!(result.centres.len(), 2);
        assert!(kmeans(
            &metric,
            &rows,
            &KMeansOptions::new(0),
            &mut SeededRng::new(0)
        )
        .is_err());
        let empty = DescriptorRows::<f32>::new(2).unwrap();
        assert!(matches!(
            kmeans(
                &metric,
                &empty,
                &KMeansOptions::new(2),
                &mut SeededRng::new(0)
            ),
            Err(PlaceError::NoDescriptors { .. })
        ));
        assert!(matches!(
            kmeans(
                &L2Float { dim: 3 },
                &rows,
                &KMeansOptions::new(2),
                &mut SeededRng::new(0)
            ),
            Err(PlaceError::RowLength { .. })
        ));
        assert!(kmeans_subset(
            &metric,
            &rows,
            &[7],
            &KMeansOptions::new(1),
            &mut SeededRng::new(0)
        )
        .is_err());
    }
}
