//! Timestamp association of two trajectories (evo's `sync.associate_trajectories`).

use super::error::{EvalError, Result};
use super::trajectory::Trajectory;

/// evo's default tolerance for associating timestamps, in seconds.
pub const DEFAULT_MAX_DIFF: f64 = 0.01;

/// Two trajectories whose poses correspond one to one.
#[derive(Debug, Clone, PartialEq)]
pub struct AssociatedPair {
    /// The reference poses kept.
    pub reference: Trajectory,
    /// The estimated poses kept, in the same order.
    pub estimate: Trajectory,
}

/// Associates the stamps of `reference` and `estimate`: like evo, every stamp of
/// the shorter trajectory is matched to the nearest stamp of the longer one when
/// they differ by at most `max_diff` seconds. Order is kept, and a stamp of the
/// longer trajectory is used at most once (a later duplicate match is dropped).
pub fn associate(
    reference: &Trajectory,
    estimate: &Trajectory,
    max_diff: f64,
) -> Result<AssociatedPair> {
    associate_with(reference, estimate, max_diff, true)
}

/// [`associate`], choosing whether matches are one to one. With `one_to_one`
/// false this is exactly evo's rule, which pairs a stamp of the longer
/// trajectory with every stamp of the shorter one that it is nearest to
/// (duplicated stamps in a file then give duplicated pairs).
pub fn associate_with(
    reference: &Trajectory,
    estimate: &Trajectory,
    max_diff: f64,
    one_to_one: bool,
) -> Result<AssociatedPair> {
    let estimate_longer = estimate.len() > reference.len();
    let (short, long) = if estimate_longer {
        (reference, estimate)
    } else {
        (estimate, reference)
    };
    let (short_ids, long_ids) =
        matching_indices(&short.timestamps, &long.timestamps, max_diff, one_to_one);
    if short_ids.is_empty() {
        return Err(EvalError::NoAssociation {
            max_diff,
            reference: reference.len(),
            estimate: estimate.len(),
        });
    }
    let (short, long) = (short.select(&short_ids), long.select(&long_ids));
    Ok(if estimate_longer {
        AssociatedPair {
            reference: short,
            estimate: long,
        }
    } else {
        AssociatedPair {
            reference: long,
            estimate: short,
        }
    })
}

/// For each stamp of `first`, the nearest stamp of `second` within `max_diff`
/// (ties go to the earlier stamp); with `one_to_one`, each stamp of `second` is used once.
fn matching_indices(
    first: &[f64],
    second: &[f64],
    max_diff: f64,
    one_to_one: bool,
) -> (Vec<usize>, Vec<usize>) {
    let mut order: Vec<usize> = (0..second.len()).collect();
    order.sort_by(|&a, &b| second[a].total_cmp(&second[b]));
    let sorted: Vec<f64> = order.iter().map(|&i| second[i]).collect();
    let (mut ids_1, mut ids_2) = (Vec::new(), Vec::new());
    let mut used = vec![false; second.len()];
    for (i, &stamp) in first.iter().enumerate() {
        let upper = sorted.partition_point(|&s| s <= stamp);
        let diff_ub = sorted.get(upper).map_or(f64::INFINITY, |s| s - stamp);
        let diff_lb = if upper > 0 {
            stamp - sorted[upper - 1]
        } else {
            f64::INFINITY
        };
        let best = if diff_ub <= max_diff && diff_ub < diff_lb {
            upper
        } else if diff_lb <= max_diff && diff_lb <= diff_ub {
            upper - 1
        } else {
            continue;
        };
        let j = order[best];
        if !one_to_one || !used[j] {
            used[j] = true;
            ids_1.push(i);
            ids_2.push(j);
        }
    }
    (ids_1, ids_2)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Isometry3;

    fn stamps(t: &[f64]) -> Trajectory {
        Trajectory::new(t.to_vec(), vec![Isometry3::identity(); t.len()])
    }

    #[test]
    fn nearest_within_tolerance_one_to_one() {
        let reference = stamps(&[0.0, 0.1, 0.2, 0.3, 0.4, 0.5]);
        let estimate = stamps(&[0.004, 0.006, 0.25, 0.398]);
        let pair = associate(&reference, &estimate, 0.01).unwrap();
        assert_eq!(pair.estimate.timestamps, vec![0.004, 0.398]);
        assert_eq!(pair.reference.timestamps, vec![0.0, 0.4]);
    }

    #[test]
    fn no_match_is_an_error() {
        let err = associate(&stamps(&[0.0, 1.0]), &stamps(&[0.5]), 0.01).unwrap_err();
        assert!(matches!(err, EvalError::NoAssociation { .. }));
    }
}
