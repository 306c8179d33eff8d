//! The brute-force matcher against a naive O(n²) reference (random float and
//! binary descriptors, with ties), with and without a train layout (the
//! ratio test's rivals beyond a descriptor cell), and the ratio / mutual
//! semantics.

use proptest::prelude::*;
use spslam::features::DescriptorSet;
use spslam::matching::{
    match_brute_force, match_brute_force_spaced, Match, MatchError, MatchParams, TrainLayout,
};

/// The reference: all distances, first index wins ties, ratio strict.
fn naive(a: &DescriptorSet, b: &DescriptorSet, p: MatchParams) -> Vec<Match> {
    naive_spaced(a, b, p, None)
}

/// The reference with a layout: the second best is the nearest train row
/// other than the best at least the best's rival distance from it.
fn naive_spaced(
    a: &DescriptorSet,
    b: &DescriptorSet,
    p: MatchParams,
    layout: Option<TrainLayout<'_>>,
) -> Vec<Match> {
    let (n, m) = (a.len(), b.len());
    let d = |i: usize, j: usize| a.distance(i, b, j).unwrap_or(f32::NAN);
    let argmin = |it: &mut dyn Iterator<Item = (usize, f32)>| {
        let mut best: Option<(usize, f32)> = None;
        for (k, v) in it {
            if best.is_none_or(|(_, bv)| v < bv) {
                best = Some((k, v));
            }
        }
        best
    };
    let mut out = Vec::new();
    for i in 0..n {
        let Some((j, dj)) = argmin(&mut (0..m).map(|j| (j, d(i, j)))) else {
            continue;
        };
        let rival = |k: usize| {
            layout.is_none_or(|l| {
                let ([xj, yj], [xk, yk]) = (l.positions[j], l.positions[k]);
                (xk - xj).hypot(yk - yj) >= l.min_rival_distance[j]
            })
        };
        let second = (0..m)
            .filter(|&k| k != j && rival(k))
            .map(|k| d(i, k))
            .fold(f32::INFINITY, f32::min);
        if dj > p.max_distance {
            continue;
        }
        if let Some(r) = p.ratio {
            if dj >= r * second {
                continue;
            }
        }
        if p.mutual && argmin(&mut (0..n).map(|q| (q, d(q, j)))).map(|x| x.0) != Some(i) {
            continue;
        }
        out.push(Match {
            query: i,
            train: j,
            distance: dj,
        });
    }
    out
}

/// Float rows from small integers, so that exact ties are common.
fn float_set(values: Vec<u8>, dim: usize) -> DescriptorSet {
    let rows = values.len() / dim;
    DescriptorSet::Float {
        dim,
        data: values[..rows * dim]
            .iter()
            .map(|&v| (v % 4) as f32 * 0.5)
            .collect(),
    }
}

/// Binary rows with few set bits, so that ties are common.
fn binary_set(values: Vec<u8>) -> DescriptorSet {
    DescriptorSet::Binary {
        data: values
            .chunks_exact(4)
            .map(|c| {
                let mut d = [0u8; 32];
                d[..4].copy_from_slice(c);
                d.iter_mut().take(4).for_each(|b| *b &= 0b0101_0011);
                d
            })
            .collect(),
    }
}

fn params() -> impl Strategy<Value = MatchParams> {
    (
        prop::option::of(0.3f32..1.2),
        prop_oneof![Just(f32::INFINITY), 0.0f32..6.0],
        any::<bool>(),
    )
        .prop_map(|(ratio, max_distance, mutual)| MatchParams {
            ratio,
            max_distance,
            mutual,
        })
}

proptest! {
    #[test]
    fn float_matches_equal_the_naive_reference(
        a in prop::collection::vec(any::<u8>(), 0..120),
        b in prop::collection::vec(any::<u8>(), 0..120),
        dim in 1usize..6,
        p in params(),
    ) {
        let (a, b) = (float_set(a, dim), float_set(b, dim));
        let got = match_brute_force(&a, &b, p).map_err(|e| TestCaseError::fail(e.to_string()))?;
        prop_assert_eq!(got, naive(&a, &b, p));
    }

    #[test]
    fn binary_matches_equal_the_naive_reference(
        a in prop::collection::vec(any::<u8>(), 0..160),
        b in prop::collection::vec(any::<u8>(), 0..160),
        p in params(),
    ) {
        let (a, b) = (binary_set(a), binary_set(b));
        let got = match_brute_force(&a, &b, p).map_err(|e| TestCaseError::fail(e.to_string()))?;
        prop_assert_eq!(got, naive(&a, &b, p));
    }
}

proptest! {
    #[test]
    fn spaced_matches_equal_the_naive_reference(
        a in prop::collection::vec(any::<u8>(), 0..120),
        b in prop::collection::vec(any::<u8>(), 0..120),
        dim in 1usize..6,
        p in params(),
        cells in prop::collection::vec((0u8..6, 0u8..6, 0u8..4), 120),
    ) {
        let (a, b) = (float_set(a, dim), float_set(b, dim));
        // Positions on a coarse grid, so that rows within a gap are common.
        let positions: Vec<[f32; 2]> =
            cells.iter().take(b.len()).map(|&(x, y, _)| [f32::from(x) * 4.0, f32::from(y) * 4.0]).collect();
        let gaps: Vec<f32> = cells.iter().take(b.len()).map(|&(_, _, g)| f32::from(g) * 4.0).collect();
        let layout = TrainLayout { positions: &positions, min_rival_distance: &gaps };
        let got = match_brute_force_spaced(&a, &b, p, Some(layout))
            .map_err(|e| TestCaseError::fail(e.to_string()))?;
        prop_assert_eq!(got, naive_spaced(&a, &b, p, Some(layout)));
    }
}

#[test]
fn a_runner_up_within_the_cell_is_no_rival() {
    // Train rows 0 and 1 look alike (one descriptor cell of a SuperPoint
    // map); row 2 is different. The query is closest to row 0.
    let query = rows(&[[0.0, 0.0]]);
    let train = rows(&[[0.1, 0.0], [0.12, 0.0], [3.0, 3.0]]);
    let p = MatchParams {
        ratio: Some(0.7),
        max_distance: f32::INFINITY,
        mutual: true,
    };
    // The plain ratio test rejects it: 0.1 >= 0.7 * 0.12.
    assert!(match_brute_force(&query, &train, p).is_ok_and(|m| m.is_empty()));
    let gaps = [8.0; 3];
    // Rows 0 and 1 seen 5 px apart: row 1 is no rival, row 2 is (0.1 < 0.7 * 4.2).
    let near = [[100.0, 100.0], [104.0, 103.0], [300.0, 50.0]];
    let layout = TrainLayout {
        positions: &near,
        min_rival_distance: &gaps,
    };
    let m = match_brute_force_spaced(&query, &train, p, Some(layout)).unwrap_or_default();
    assert_eq!(
        m.iter().map(|m| (m.query, m.train)).collect::<Vec<_>>(),
        vec![(0, 0)]
    );
    // Seen 20 px apart, the two are distinct points that look alike: rejected.
    let far = [[100.0, 100.0], [120.0, 100.0], [300.0, 50.0]];
    let layout = TrainLayout {
        positions: &far,
        min_rival_distance: &gaps,
    };
    assert!(match_brute_force_spaced(&query, &train, p, Some(layout)).is_ok_and(|m| m.is_empty()));
    // A layout of the wrong length is an error that names the counts.
    let short = TrainLayout {
        positions: &far[..2],
        min_rival_distance: &gaps,
    };
    assert!(matches!(
        match_brute_force_spaced(&query, &train, p, Some(short)),
        Err(MatchError::LayoutLength {
            rows: 3,
            positions: 2,
            distances: 3
        })
    ));
}

fn rows(rows: &[[f32; 2]]) -> DescriptorSet {
    DescriptorSet::Float {
        dim: 2,
        data: rows.iter().flatten().copied().collect(),
    }
}

#[test]
fn ratio_rejects_ambiguous_and_ties() {
    let query = rows(&[[0.0, 0.0]]);
    let train = rows(&[[1.0, 0.0], [0.0, 1.0], [5.0, 5.0]]);
    let p = MatchParams {
        ratio: Some(0.99),
        max_distance: f32::INFINITY,
        mutual: false,
    };
    // Two candidates at exactly the same distance: the ratio test fails.
    assert!(match_brute_force(&query, &train, p)
        .unwrap_or_default()
        .is_empty());
    // Without a ratio test, the first of the tied candidates wins.
    let no_ratio = MatchParams { ratio: None, ..p };
    let m = match_brute_force(&query, &train, no_ratio).unwrap_or_default();
    assert_eq!(
        m,
        vec![Match {
            query: 0,
            train: 0,
            distance: 1.0
        }]
    );
    // A clear winner passes ratio 0.7: 0.1 < 0.7 * 1.0.
    let clear = rows(&[[0.1, 0.0], [0.0, 1.0]]);
    let m = match_brute_force(
        &query,
        &clear,
        MatchParams {
            ratio: Some(0.7),
            ..p
        },
    )
    .unwrap_or_default();
    assert_eq!(m.len(), 1);
    // max_distance is inclusive.
    let m = match_brute_force(
        &query,
        &train,
        MatchParams {
            max_distance: 1.0,
            ..no_ratio
        },
    )
    .unwrap_or_default();
    assert_eq!(m.len(), 1);
    let m = match_brute_force(
        &query,
        &train,
        MatchParams {
            max_distance: 0.99,
            ..no_ratio
        },
    )
    .unwrap_or_default();
    assert!(m.is_empty());
}

#[test]
fn mutual_keeps_only_the_trains_nearest_query() {
    let query = rows(&[[0.0, 0.0], [0.2, 0.0]]);
    let train = rows(&[[0.3, 0.0], [9.0, 9.0]]);
    let p = MatchParams {
        ratio: None,
        max_distance: f32::INFINITY,
        mutual: true,
    };
    // Both queries' nearest is train 0, whose nearest query is 1.
    let m = match_brute_force(&query, &train, p).unwrap_or_default();
    assert_eq!(
        m.iter().map(|m| (m.query, m.train)).collect::<Vec<_>>(),
        vec![(1, 0)]
    );
    let m =
        match_brute_force(&query, &train, MatchParams { mutual: false, ..p }).unwrap_or_default();
    assert_eq!(m.len(), 2);
}

#[test]
fn kinds_must_agree_and_parameters_be_valid() {
    let f = rows(&[[0.0, 0.0]]);
    let b = DescriptorSet::Binary {
        data: vec![[0u8; 32]],
    };
    assert!(matches!(
        match_brute_force(&f, &b, MatchParams::default()),
        Err(MatchError::KindMismatch { .. })
    ));
    let f3 = DescriptorSet::Float {
        dim: 3,
        data: vec![0.0; 3],
    };
    assert!(matches!(
        match_brute_force(&f, &f3, MatchParams::default()),
        Err(MatchError::KindMismatch { .. })
    ));
    let bad = MatchParams {
        ratio: Some(-1.0),
        ..MatchParams::default()
    };
    assert!(matches!(
        match_brute_force(&f, &f, bad),
        Err(MatchError::InvalidParameter { .. })
    ));
    assert!(match_brute_force(&b, &b, MatchParams::default()).is_ok_and(|m| m.len() == 1));
}
