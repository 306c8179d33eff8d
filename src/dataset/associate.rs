//! Timestamp association as in TUM's `associate.py`: nearest pairs within a
//! tolerance, one-to-one, greedily by increasing time difference.

/// A matched pair of indices into the two timestamp lists.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Association {
    /// Index into the first list.
    pub first: usize,
    /// Index into the second list.
    pub second: usize,
}

/// Associates two timestamp lists (seconds; need not be sorted).
///
/// Every pair with `|a − b| < max_difference` is a candidate; candidates are
/// taken by increasing difference (ties by earlier `a`, then earlier `b`), each
/// index being used at most once. The result is sorted by the first timestamp.
pub fn associate(first: &[f64], second: &[f64], max_difference: f64) -> Vec<Association> {
    let mut order: Vec<usize> = (0..second.len()).collect();
    order.sort_by(|&a, &b| second[a].total_cmp(&second[b]));
    let sorted: Vec<f64> = order.iter().map(|&i| second[i]).collect();

    let mut candidates: Vec<(f64, usize, usize)> = Vec::new();
    for (i, &a) in first.iter().enumerate() {
        let start = sorted.partition_point(|&b| b <= a - max_difference);
        for (k, &b) in sorted.iter().enumerate().skip(start) {
            if b >= a + max_difference {
                break;
            }
            let d = (a - b).abs();
            if d < max_difference {
                candidates.push((d, i, order[k]));
            }
        }
    }
    candidates.sort_by(|x, y| {
        x.0.total_cmp(&y.0)
            .then(first[x.1].total_cmp(&first[y.1]))
            .then(second[x.2].total_cmp(&second[y.2]))
    });

    let mut used_first = vec![false; first.len()];
    let mut used_second = vec![false; second.len()];
    let mut matches = Vec::new();
    for (_, i, j) in candidates {
        if !used_first[i] && !used_second[j] {
            used_first[i] = true;
            used_second[j] = true;
            matches.push(Association {
                first: i,
                second: j,
            });
        }
    }
    matches.sort_by(|x, y| first[x.first].total_cmp(&first[y.first]));
    matches
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_one_to_one_within_tolerance() {
        let rgb = [1.00, 1.03, 1.10, 2.00];
        let depth = [1.01, 1.105, 1.50];
        let m = associate(&rgb, &depth, 0.02);
        // 1.00↔1.01 (0.01); 1.03 would also like 1.01 (0.02, not < 0.02);
        // 1.10↔1.105; 2.00 and 1.50 have no partner.
        assert_eq!(
            m,
            vec![
                Association {
                    first: 0,
                    second: 0
                },
                Association {
                    first: 2,
                    second: 1
                },
            ]
        );
    }

    #[test]
    fn contested_partner_goes_to_the_nearest() {
        let m = associate(&[1.000, 1.012], &[1.010], 0.02);
        assert_eq!(
            m,
            vec![Association {
                first: 1,
                second: 0
            }]
        );
    }

    #[test]
    fn empty_inputs() {
        assert!(associate(&[], &[1.0], 0.02).is_empty());
        assert!(associate(&[1.0], &[], 0.02).is_empty());
    }
}
