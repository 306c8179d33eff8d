//! All-pairs matching with Lowe's ratio test and a mutual (cross) check.

use super::l2_rows::for_each_l2_row;
use super::{check_kinds, BestTwo, MatchError};
use crate::features::descriptor_set::DescriptorDistance;
use crate::features::DescriptorSet;

/// A correspondence between query row `query` and train row `train`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Match {
    /// Index on the query side.
    pub query: usize,
    /// Index on the train side.
    pub train: usize,
    /// Descriptor distance (L2, or Hamming bits).
    pub distance: f32,
}

/// The tests a brute-force match must pass.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MatchParams {
    /// Lowe's ratio: best < ratio * second best (strict; ties fail).
    /// `None` disables the test. The paper uses 0.7.
    pub ratio: Option<f32>,
    /// The best distance must be at most this.
    pub max_distance: f32,
    /// Keep a match only when the query is also the train row's nearest query
    /// (the first one on ties).
    pub mutual: bool,
}

impl Default for MatchParams {
    /// Ratio 0.7, no distance limit, mutual check on.
    fn default() -> Self {
        Self {
            ratio: Some(0.7),
            max_distance: f32::INFINITY,
            mutual: true,
        }
    }
}

/// Where each train row was seen, for a ratio test that does not pit two
/// rows from one descriptor cell against each other (see
/// [`match_brute_force_spaced`]).
#[derive(Clone, Copy, Debug)]
pub struct TrainLayout<'a> {
    /// Each train row's keypoint in its source view, in level-0 pixels.
    pub positions: &'a [[f32; 2]],
    /// Each train row's rival distance in level-0 pixels: a second-best
    /// row closer than the best row's value to the best row's keypoint is
    /// not its rival (the descriptor cell scaled by the keypoint's octave;
    /// 0 for descriptors computed at each keypoint).
    pub min_rival_distance: &'a [f32],
}

/// Matches every query row against all train rows. Returns the accepted
/// matches in query order. Errors when the kinds differ or a parameter is
/// out of range.
pub fn match_brute_force(
    query: &DescriptorSet,
    train: &DescriptorSet,
    params: MatchParams,
) -> Result<Vec<Match>, MatchError> {
    match_brute_force_spaced(query, train, params, None)
}

/// [`match_brute_force`] where the train rows come from one view and
/// `layout` says where: the ratio test's second best is sought only among
/// train rows at least the best row's `min_rival_distance` from it, as
/// [`ProjectionParams::min_rival_distance`](super::ProjectionParams::min_rival_distance)
/// does for the search by projection. SuperPoint's descriptors are sampled
/// from a map with one vector per 8×8 cell, so two points of one view less
/// than a cell apart share most of their descriptor, and the plain ratio
/// test drops a frame keypoint whose true point has such a neighbour.
/// Errors when the kinds differ, a parameter is out of range, or the
/// layout's length is not the train rows'.
pub fn match_brute_force_spaced(
    query: &DescriptorSet,
    train: &DescriptorSet,
    params: MatchParams,
    layout: Option<TrainLayout<'_>>,
) -> Result<Vec<Match>, MatchError> {
    check_kinds(query.kind(), train.kind())?;
    if let Some(l) = layout {
        let rows = train.len();
        if l.positions.len() != rows || l.min_rival_distance.len() != rows {
            return Err(MatchError::LayoutLength {
                rows,
                positions: l.positions.len(),
                distances: l.min_rival_distance.len(),
            });
        }
    }
    if let Some(r) = params.ratio {
        if !(r.is_finite() && r > 0.0) {
            return Err(MatchError::InvalidParameter {
                name: "ratio",
                value: r,
                expected: "a positive number (or None)",
            });
        }
    }
    if params.max_distance.is_nan() || params.max_distance < 0.0 {
        return Err(MatchError::InvalidParameter {
            name: "max_distance",
            value: params.max_distance,
            expected: ">= 0",
        });
    }
    Ok(match (query, train) {
        (DescriptorSet::Float { dim, data: q }, DescriptorSet::Float { data: t, .. }) => {
            if *dim == 0 {
                return Ok(Vec::new());
            }
            let (n_query, n_train) = (q.len() / dim, t.len() / dim);
            let mut matches = match_rows(n_query, n_train, params, layout, |rows| {
                for_each_l2_row(q, t, *dim, rows)
            });
            // The product's distances decide; the one reported is computed
            // directly, the same number every other matcher reports.
            for m in &mut matches {
                let (a, b) = (m.query * dim, m.train * dim);
                m.distance = q[a..a + dim].distance_to(&t[b..b + dim]);
            }
            matches
        }
        (DescriptorSet::Binary { data: q }, DescriptorSet::Binary { data: t }) => {
            match_rows(q.len(), t.len(), params, layout, |row| {
                let mut distances = vec![0.0f32; t.len()];
                for (i, a) in q.iter().enumerate() {
                    for (d, b) in distances.iter_mut().zip(t) {
                        *d = a.distance_to(b);
                    }
                    row(i, &distances);
                }
            })
        }
        _ => Vec::new(), // unreachable after check_kinds
    })
}

/// The smallest distance of a row other than `best` whose keypoint lies at
/// least `best`'s rival distance from `best`'s (infinite when none does).
fn second_beyond_cell(distances: &[f32], layout: TrainLayout<'_>, best: usize) -> f32 {
    let [bx, by] = layout.positions[best];
    let gap = layout.min_rival_distance[best];
    distances
        .iter()
        .zip(layout.positions)
        .enumerate()
        .filter(|&(j, (_, [x, y]))| j != best && (x - bx).hypot(y - by) >= gap)
        .map(|(_, (&d, _))| d)
        .fold(f32::INFINITY, f32::min)
}

/// The one decision for both metrics: `rows` hands over each query row's
/// distances to every train row, in ascending query order.
fn match_rows(
    n_query: usize,
    n_train: usize,
    params: MatchParams,
    layout: Option<TrainLayout<'_>>,
    rows: impl FnOnce(&mut dyn FnMut(usize, &[f32])),
) -> Vec<Match> {
    let mut column_best: Vec<Option<(usize, f32)>> = vec![None; n_train];
    let mut row_best = Vec::with_capacity(n_query);
    rows(&mut |i, distances| {
        let mut best = BestTwo::default();
        for (j, &d) in distances.iter().enumerate() {
            best.offer(j, d);
            if params.mutual && column_best[j].is_none_or(|(_, cd)| d < cd) {
                column_best[j] = Some((i, d));
            }
        }
        if let (Some(layout), Some((b, _))) = (layout, best.best) {
            best.second = second_beyond_cell(distances, layout, b);
        }
        row_best.push(best);
    });
    row_best
        .iter()
        .enumerate()
        .filter_map(|(i, best)| {
            let (j, d) = best.accept(params.max_distance, params.ratio)?;
            if params.mutual && column_best[j].map(|(qi, _)| qi) != Some(i) {
                return None;
            }
            Some(Match {
                query: i,
                train: j,
                distance: d,
            })
        })
        .collect()
}
