//! ORB-SLAM3's rotation-consistency check: a histogram of the keypoint angle
//! change over the matches; only the three most populated bins survive.

use super::Match;
use crate::features::Keypoint;

/// Keeps the matches whose angle change (train − query, degrees) falls in
/// one of the three fullest of `bins` histogram bins. ORB-SLAM3 (`HISTO_LENGTH`
/// 30) drops the second and third bins when they hold less than a tenth of
/// the first; so does this.
pub fn keep_consistent_rotation(
    matches: &mut Vec<Match>,
    query: &[Keypoint],
    train: &[Keypoint],
    bins: usize,
) {
    if bins == 0 || matches.is_empty() {
        return;
    }
    let bin_of = |m: &Match| -> Option<usize> {
        let a = query.get(m.query)?.angle;
        let b = train.get(m.train)?.angle;
        let rot = (b - a).rem_euclid(360.0);
        Some(((rot / 360.0 * bins as f32) as usize).min(bins - 1))
    };
    let mut counts = vec![0usize; bins];
    for m in matches.iter() {
        if let Some(b) = bin_of(m) {
            counts[b] += 1;
        }
    }
    let mut order: Vec<usize> = (0..bins).collect();
    order.sort_by_key(|&b| (std::cmp::Reverse(counts[b]), b));
    let first = counts[order[0]];
    let kept: Vec<usize> = order
        .iter()
        .take(3)
        .enumerate()
        .filter(|&(rank, &b)| counts[b] > 0 && (rank == 0 || counts[b] * 10 >= first))
        .map(|(_, &b)| b)
        .collect();
    matches.retain(|m| bin_of(m).is_some_and(|b| kept.contains(&b)));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outlying_rotations_are_dropped() {
        let kp = |angle| Keypoint {
            x: 0.0,
            y: 0.0,
            size: 31.0,
            angle,
            response: 1.0,
            octave: 0,
        };
        let query: Vec<Keypoint> = (0..22).map(|_| kp(10.0)).collect();
        let mut train: Vec<Keypoint> = (0..20).map(|i| kp(12.0 + (i % 3) as f32)).collect();
        train.push(kp(190.0));
        train.push(kp(100.0));
        let mut matches: Vec<Match> = (0..22)
            .map(|i| Match {
                query: i,
                train: i,
                distance: 0.0,
            })
            .collect();
        keep_consistent_rotation(&mut matches, &query, &train, 30);
        assert_eq!(matches.len(), 20);
    }
}
