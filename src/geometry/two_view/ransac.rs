//! Deterministic RANSAC sampling and the hypothesise-and-score loop shared by
//! the homography and the fundamental matrix (ORB-SLAM3's `FindHomography` /
//! `FindFundamental`).

use nalgebra::{Matrix3, Point2};

/// Matches per minimal sample (the 8-point algorithm; the DLT uses the same sets).
pub(crate) const SAMPLE_SIZE: usize = 8;

/// SplitMix64: a small, seeded, well-mixed 64-bit generator (Steele, Lea and
/// Flood 2014). Same seed, same sequence, on every platform.
#[derive(Debug, Clone)]
pub(crate) struct SplitMix64(u64);

impl SplitMix64 {
    /// A generator from its seed.
    pub(crate) fn new(seed: u64) -> Self {
        Self(seed)
    }

    /// The next 64 random bits.
    pub(crate) fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `0..n` (Lemire's multiply-shift; `n == 0` gives 0).
    pub(crate) fn below(&mut self, n: usize) -> usize {
        ((u128::from(self.next_u64()) * n as u128) >> 64) as usize
    }

    /// Uniform in `[0, 1)`.
    #[cfg_attr(not(test), allow(dead_code))]
    pub(crate) fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

/// `iterations` sets of [`SAMPLE_SIZE`] distinct indices in `0..n`, drawn as
/// ORB-SLAM3's `Reconstruct` does (swap-remove from the available indices).
/// Empty when `n < SAMPLE_SIZE`.
pub(crate) fn sample_sets(n: usize, iterations: usize, seed: u64) -> Vec<[usize; SAMPLE_SIZE]> {
    if n < SAMPLE_SIZE {
        return Vec::new();
    }
    let mut rng = SplitMix64::new(seed);
    let all: Vec<usize> = (0..n).collect();
    let mut sets = Vec::with_capacity(iterations);
    let mut available = Vec::with_capacity(n);
    for _ in 0..iterations {
        available.clear();
        available.extend_from_slice(&all);
        let mut set = [0usize; SAMPLE_SIZE];
        for slot in &mut set {
            let k = rng.below(available.len());
            *slot = available.swap_remove(k);
        }
        sets.push(set);
    }
    sets
}

/// The best model a RANSAC loop found.
#[derive(Debug, Clone)]
pub(crate) struct RansacResult {
    /// The model, in pixel coordinates.
    pub model: Matrix3<f64>,
    /// Its score (ORB-SLAM3's `CheckHomography` / `CheckFundamental`).
    pub score: f64,
    /// Its inliers, one flag per match.
    pub inliers: Vec<bool>,
}

/// The RANSAC loop of `FindHomography` / `FindFundamental`: for each sample
/// set, `solve` fits a pixel-coordinate model from the normalised sample
/// points, `score` scores it on all matches; the highest score wins (ties
/// keep the earlier model, as ORB-SLAM3's strict `>`). The winner is then
/// refitted by `solve` on all its inliers, re-scored, and the refit kept
/// while it raises the score (up to [`REFIT_ROUNDS`] times). `None` when no
/// model scores above zero.
pub(crate) fn best_model<S, C>(
    sets: &[[usize; SAMPLE_SIZE]],
    n1: &[Point2<f64>],
    n2: &[Point2<f64>],
    mut solve: S,
    mut score: C,
) -> Option<RansacResult>
where
    S: FnMut(&[Point2<f64>], &[Point2<f64>]) -> Option<Matrix3<f64>>,
    C: FnMut(&Matrix3<f64>, &mut [bool]) -> f64,
{
    let n = n1.len().min(n2.len());
    let mut best: Option<RansacResult> = None;
    let mut current = vec![false; n];
    let mut s1 = [Point2::origin(); SAMPLE_SIZE];
    let mut s2 = [Point2::origin(); SAMPLE_SIZE];
    for set in sets {
        for (j, &idx) in set.iter().enumerate() {
            s1[j] = n1[idx];
            s2[j] = n2[idx];
        }
        let Some(model) = solve(&s1, &s2) else {
            continue;
        };
        let s = score(&model, &mut current);
        let best_score = best.as_ref().map_or(0.0, |b| b.score);
        if s.is_finite() && s > best_score {
            best = Some(RansacResult {
                model,
                score: s,
                inliers: current.clone(),
            });
        }
    }
    let mut best = best?;
    // Least-squares refit on the inliers (not in ORB-SLAM3, whose minimal
    // 8-point models are left to the initial bundle adjustment): kept only
    // while it raises the score.
    let mut r1 = Vec::with_capacity(n);
    let mut r2 = Vec::with_capacity(n);
    for _ in 0..REFIT_ROUNDS {
        r1.clear();
        r2.clear();
        for (i, _) in best.inliers.iter().enumerate().filter(|(_, &b)| b) {
            r1.push(n1[i]);
            r2.push(n2[i]);
        }
        if r1.len() <= SAMPLE_SIZE {
            break;
        }
        let Some(model) = solve(&r1, &r2) else {
            break;
        };
        let s = score(&model, &mut current);
        if !(s.is_finite() && s > best.score) {
            break;
        }
        best = RansacResult {
            model,
            score: s,
            inliers: current.clone(),
        };
    }
    Some(best)
}

/// Rounds of inlier refitting after the RANSAC loop.
const REFIT_ROUNDS: usize = 5;
