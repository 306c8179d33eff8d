//! Keypoint selection: the paper's ANMS on a kd-tree, Bailo et al.'s SSC, and top-N.
//!
//! Every function takes the NMS candidates and a target count `n`, and returns
//! indices into the input slice, in selection order, without duplicates. None
//! of them panics, whatever the input (empty input, `n == 0`, `n > len`, NaN
//! or infinite scores or coordinates, duplicate positions).
//!
//! # Strength order
//!
//! All methods rank candidates by *strength*: score descending, ties broken by
//! the lower input index. NaN scores are the weakest of all (below
//! `-inf`); NaN-scored candidates are ordered among themselves by index.
//! `-0.0` and `0.0` are equal scores. Candidate `a` is *stronger* than `b` iff
//! `a` comes before `b` in this order.

use std::cmp::Ordering;

use super::AnmsMethod;

/// A detection candidate: position and score.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Candidate {
    /// Column in pixels.
    pub x: f32,
    /// Row in pixels.
    pub y: f32,
    /// Detector score; higher is stronger.
    pub score: f32,
}

/// Tolerance on the kept count used by [`select`] for [`AnmsMethod::Ssc`].
pub const SSC_TOLERANCE: f32 = 0.1;

/// Largest coordinate magnitude the ANMS radius computation accepts; see
/// [`anms_kdtree`]. Squared distances between such points cannot overflow `f32`.
pub const MAX_COORDINATE: f32 = 1.0e15;

/// Upper bound on the number of SSC grid cells (bytes) allocated at once.
const SSC_MAX_GRID_CELLS: usize = 1 << 26;

/// Maps a score to a `u32` whose ascending order is the score's ascending order,
/// with NaN below everything (key 0) and `-0.0 == 0.0`.
#[inline]
fn score_key(s: f32) -> u32 {
    if s.is_nan() {
        return 0;
    }
    // `+ 0.0` turns -0.0 into +0.0.
    let bits = (s + 0.0).to_bits();
    if bits & 0x8000_0000 != 0 {
        !bits
    } else {
        bits | 0x8000_0000
    }
}

/// Indices of `candidates` in strength order (strongest first).
fn strength_order(candidates: &[Candidate]) -> Vec<usize> {
    let len = candidates.len();
    if len <= u32::MAX as usize {
        // Pack (descending score, ascending index) into one u64 for a fast sort.
        let mut keys: Vec<u64> = candidates
            .iter()
            .enumerate()
            .map(|(i, c)| (u64::from(!score_key(c.score)) << 32) | i as u64)
            .collect();
        keys.sort_unstable();
        keys.into_iter()
            .map(|k| (k & 0xFFFF_FFFF) as usize)
            .collect()
    } else {
        let mut keys: Vec<(u32, usize)> = candidates
            .iter()
            .enumerate()
            .map(|(i, c)| (!score_key(c.score), i))
            .collect();
        keys.sort_unstable();
        keys.into_iter().map(|(_, i)| i).collect()
    }
}

/// Selects the `n` strongest candidates (see the module docs for the strength
/// order: score descending, ties by lower index, NaN scores weakest).
///
/// Returns `min(n, candidates.len())` indices, strongest first. Runs in
/// `O(len + n log n)`.
pub fn select_top_n(candidates: &[Candidate], n: usize) -> Vec<usize> {
    let len = candidates.len();
    let n = n.min(len);
    if n == 0 {
        return Vec::new();
    }
    if n == len {
        return strength_order(candidates);
    }
    // (descending score, ascending index) as a u128 key works for any index width.
    let mut keys: Vec<u128> = candidates
        .iter()
        .enumerate()
        .map(|(i, c)| (u128::from(!score_key(c.score)) << 64) | i as u128)
        .collect();
    keys.select_nth_unstable(n - 1);
    keys.truncate(n);
    keys.sort_unstable();
    keys.into_iter().map(|k| k as u64 as usize).collect()
}

/// Whether a position takes part in the ANMS radius computation.
#[inline]
fn valid_position(c: &Candidate) -> bool {
    c.x.abs() <= MAX_COORDINATE && c.y.abs() <= MAX_COORDINATE
}

/// The squared distance used by both ANMS implementations, in `f32`.
#[inline]
fn sq_dist(a: [f32; 2], b: [f32; 2]) -> f32 {
    let dx = a[0] - b[0];
    let dy = a[1] - b[1];
    dx * dx + dy * dy
}

/// Squared suppression radius given to candidates with an invalid position.
const INVALID_RADIUS: f32 = -1.0;

/// Keeps the `n` largest radii (`radii[rank]`, rank = position in `order`),
/// ordered by radius descending, ties by rank; maps back to input indices.
fn keep_largest_radii(order: &[usize], radii: &[f32], n: usize) -> Vec<usize> {
    let n = n.min(order.len()).min(radii.len());
    if n == 0 {
        return Vec::new();
    }
    let cmp = |&a: &usize, &b: &usize| -> Ordering {
        let ra = radii.get(a).copied().unwrap_or(INVALID_RADIUS);
        let rb = radii.get(b).copied().unwrap_or(INVALID_RADIUS);
        rb.total_cmp(&ra).then(a.cmp(&b))
    };
    let mut ranks: Vec<usize> = (0..radii.len()).collect();
    if n < ranks.len() {
        ranks.select_nth_unstable_by(n - 1, cmp);
        ranks.truncate(n);
    }
    ranks.sort_unstable_by(cmp);
    ranks
        .into_iter()
        .filter_map(|r| order.get(r).copied())
        .collect()
}

/// The paper's adaptive non-maximal suppression (the `kdtree` method), with a
/// spatial index for the nearest-stronger search.
///
/// Candidates are ranked in strength order (module docs). Each candidate's
/// suppression radius `r` is the Euclidean distance to the nearest stronger
/// candidate (`+inf` for the strongest). The `min(n, len)` candidates with the
/// largest `r` are returned, ordered by `r` descending, ties by strength.
///
/// Distances are compared as squared distances `dx*dx + dy*dy` computed in
/// `f32`, so the result is exactly that of [`anms_brute_force`].
///
/// Candidates whose `x` or `y` is not finite or exceeds [`MAX_COORDINATE`] in
/// magnitude have no meaningful position: they never suppress anything, and
/// they rank after every candidate with a valid position (among themselves in
/// strength order). The strongest valid candidate has `r = +inf`.
///
/// Points are added to the index in strength order, each one queried for its
/// nearest (stronger) neighbour before insertion; exact duplicates of a
/// stronger point get `r = 0` without being inserted. The index is a uniform
/// bucket grid rather than a kd-tree, because kiddo 6.3.0's kd-tree returned
/// wrong nearest neighbours (see `radii_indexed`); the name of the method is
/// kept because it is the paper's algorithm.
pub fn anms_kdtree(candidates: &[Candidate], n: usize) -> Vec<usize> {
    let len = candidates.len();
    if n == 0 || len == 0 {
        return Vec::new();
    }
    if len > u32::MAX as usize {
        return anms_brute_force(candidates, n);
    }
    let order = strength_order(candidates);
    let radii = radii_indexed(candidates, &order);
    keep_largest_radii(&order, &radii, n)
}

/// Squared suppression radii by strength rank, computed with a spatial index.
///
/// kiddo 6.3.0's mutable kd-tree (`add` + `nearest_one`) was found to return a
/// wrong nearest neighbour on small inputs with many equal coordinates (e.g.
/// 66 points on a few rows and columns, no failed insertion), and to refuse
/// insertions into full buckets of equal coordinates. Since the result must be
/// exact, the index is an incremental uniform bucket grid instead: points are
/// inserted in strength order, and each query scans rings of cells around the
/// point until no unscanned cell can hold a closer point. About one point per
/// cell: `O(len)` expected work for spread-out inputs.
fn radii_indexed(candidates: &[Candidate], order: &[usize]) -> Vec<f32> {
    let len = order.len();
    let mut radii = vec![INVALID_RADIUS; len];
    // Valid positions in strength order, with their ranks.
    let pts: Vec<(usize, [f32; 2])> = order
        .iter()
        .enumerate()
        .filter_map(|(rank, &i)| {
            let c = candidates.get(i)?;
            valid_position(c).then_some((rank, [c.x, c.y]))
        })
        .collect();
    if pts.is_empty() {
        return radii;
    }
    let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    for &(_, [x, y]) in &pts {
        x0 = x0.min(f64::from(x));
        x1 = x1.max(f64::from(x));
        y0 = y0.min(f64::from(y));
        y1 = y1.max(f64::from(y));
    }
    let (w, h) = ((x1 - x0).max(0.0), (y1 - y0).max(0.0));
    let m = pts.len() as f64;
    let mut cell = (w * h / m).sqrt();
    if !(cell.is_finite() && cell > 0.0) {
        cell = (w.max(h) / m).max(f64::MIN_POSITIVE);
    }
    // At most about 4 * len cells.
    let side_max = 2.0 * m.sqrt() + 1.0;
    cell = cell.max(w / side_max).max(h / side_max);
    if !(cell.is_finite() && cell > 0.0) {
        cell = 1.0;
    }
    let gw = ((w / cell).floor() as usize).saturating_add(1).max(1);
    let gh = ((h / cell).floor() as usize).saturating_add(1).max(1);
    let cell_of = |p: [f32; 2]| -> (usize, usize) {
        let cx = ((f64::from(p[0]) - x0) / cell).floor() as usize;
        let cy = ((f64::from(p[1]) - y0) / cell).floor() as usize;
        (cx.min(gw - 1), cy.min(gh - 1))
    };
    const NONE: u32 = u32::MAX;
    let mut head = vec![NONE; gw.saturating_mul(gh)];
    let mut next = vec![NONE; pts.len()];

    for (k, &(rank, p)) in pts.iter().enumerate() {
        let (cx, cy) = cell_of(p);
        let mut best = f32::INFINITY;
        let max_ring = gw.max(gh);
        let mut ring = 0usize;
        loop {
            // Scan the cells at Chebyshev distance `ring` from (cx, cy).
            let rx0 = cx.saturating_sub(ring);
            let rx1 = (cx + ring).min(gw - 1);
            let ry0 = cy.saturating_sub(ring);
            let ry1 = (cy + ring).min(gh - 1);
            for gy in ry0..=ry1 {
                let on_edge_row = gy + ring == cy || gy == cy + ring;
                let mut gx = rx0;
                while gx <= rx1 {
                    let mut j = head.get(gy * gw + gx).copied().unwrap_or(NONE);
                    while let Some(&(_, q)) = pts.get(j as usize) {
                        best = best.min(sq_dist(p, q));
                        j = next.get(j as usize).copied().unwrap_or(NONE);
                    }
                    if on_edge_row || gx + ring != cx || ring == 0 {
                        gx += 1;
                    } else {
                        // Skip the ring's interior on this row.
                        gx = (cx + ring).max(gx + 1);
                    }
                }
            }
            if ring >= max_ring {
                break;
            }
            // Any point in a cell beyond this ring is at least `ring * cell`
            // away along one axis; keep a margin for f32 rounding.
            let bound = ring as f64 * cell;
            if f64::from(best) < bound * bound * (1.0 - 1e-5) {
                break;
            }
            ring += 1;
        }
        if let Some(r) = radii.get_mut(rank) {
            *r = best;
        }
        if let Some(hd) = head.get_mut(cy * gw + cx) {
            if let Some(nx) = next.get_mut(k) {
                *nx = *hd;
            }
            *hd = k as u32;
        }
    }
    radii
}

/// The `O(len²)` reference for [`anms_kdtree`], with exactly the same
/// semantics and output.
pub fn anms_brute_force(candidates: &[Candidate], n: usize) -> Vec<usize> {
    let len = candidates.len();
    if n == 0 || len == 0 {
        return Vec::new();
    }
    let order = strength_order(candidates);
    let radii = radii_brute_force(candidates, &order);
    keep_largest_radii(&order, &radii, n)
}

/// Squared suppression radii by strength rank, computed by exhaustive search.
fn radii_brute_force(candidates: &[Candidate], order: &[usize]) -> Vec<f32> {
    let len = order.len();
    // Valid positions seen so far, in strength order.
    let mut stronger: Vec<[f32; 2]> = Vec::with_capacity(len);
    let mut radii = vec![INVALID_RADIUS; len];
    for (rank, &idx) in order.iter().enumerate() {
        let Some(c) = candidates.get(idx) else {
            continue;
        };
        if !valid_position(c) {
            continue;
        }
        let p = [c.x, c.y];
        let best = stronger
            .iter()
            .fold(f32::INFINITY, |m, &q| m.min(sq_dist(p, q)));
        if let Some(r) = radii.get_mut(rank) {
            *r = best;
        }
        stronger.push(p);
    }
    radii
}

/// Bailo et al. 2018, "Efficient adaptive non-maximal suppression algorithms
/// for homogeneous spatial keypoint distribution" (SSC: suppression via
/// square covering), ported from the `ssc` function of BAILOOL/ANMS-Codes.
///
/// Candidates are processed in strength order (module docs). For a cell width
/// `w`, the image (`cols` × `rows`) is divided into square cells of side
/// `w / 2`; each candidate whose cell is not yet covered is kept and covers the
/// cells within two cells of its own (a square of side about `2w`). A binary
/// search on the integer `w` runs from `low = max(1, floor(sqrt(len / n)))` to
/// `high` = the positive root of the reference's quadratic (clamped to
/// `[low, max(cols, rows)]`; `max(cols, rows)` when the root is undefined, e.g.
/// `n == 1`).
///
/// Unlike the reference, which stops at any width keeping a count within
/// `n (1 ± tolerance)`, the search keeps the widest grid that keeps at least
/// `n`, and stops early only when that count is within `n (1 + tolerance)` and
/// the grid removed at least one candidate. With a candidate pool close to
/// `n` (usual after NMS), the reference would stop at a grid that removes
/// nothing and so return the top-N; this version spreads the points instead.
///
/// Differences from the reference, so that exactly `min(n, len)` indices come
/// back:
/// - more than `n` kept: truncated to the first `n` (selection order is
///   strength order, so these are the `n` strongest kept ones);
/// - fewer than `n` kept (only when no width kept `n`): filled up with the
///   strongest candidates that were not kept, appended in strength order;
/// - `n >= len`: every candidate, in strength order.
///
/// Other robustness choices: `tolerance` is clamped to `[0, 1]` (NaN → 0);
/// `cols` and `rows` of 0 count as 1; positions outside the image (and NaN
/// positions, as 0) are clamped onto the border cells; the width search never
/// allocates a grid of more than 2^26 cells (its lower end is raised instead).
/// The strongest candidate is always the first index returned (for `n ≥ 1`).
pub fn anms_ssc(
    candidates: &[Candidate],
    n: usize,
    tolerance: f32,
    cols: usize,
    rows: usize,
) -> Vec<usize> {
    let len = candidates.len();
    let n = n.min(len);
    if n == 0 {
        return Vec::new();
    }
    let order = strength_order(candidates);
    if n == len {
        return order;
    }
    let pts: Vec<[f32; 2]> = order
        .iter()
        .map(|&i| candidates.get(i).map_or([0.0, 0.0], |c| [c.x, c.y]))
        .collect();

    let cols_f = cols.max(1) as f64;
    let rows_f = rows.max(1) as f64;
    let k = n as f64;
    let tol = if tolerance.is_nan() {
        0.0
    } else {
        f64::from(tolerance.clamp(0.0, 1.0))
    };
    let k_max = (k + k * tol).round();

    // Binary search range from the reference's quadratic.
    let exp1 = rows_f + cols_f + 2.0 * k;
    let exp2 = 4.0 * cols_f + 4.0 * k + 4.0 * rows_f * k + rows_f * rows_f + cols_f * cols_f
        - 2.0 * rows_f * cols_f
        + 4.0 * rows_f * cols_f * k;
    let exp3 = exp2.max(0.0).sqrt();
    let exp4 = k - 1.0;
    let sol1 = -((exp1 + exp3) / exp4).round();
    let sol2 = -((exp1 - exp3) / exp4).round();
    let max_dim = cols_f.max(rows_f);
    let root = sol1.max(sol2);
    let mut high = if root.is_finite() && root >= 1.0 {
        root.min(max_dim)
    } else {
        max_dim
    } as i64;
    let mut low = ((len as f64 / k).sqrt().floor() as i64).max(1);
    // Grid size (columns, rows) for a width, in f64 so that it cannot overflow.
    let grid_dims = |width: i64| -> (f64, f64) {
        let c = width as f64 / 2.0;
        ((cols_f / c).floor() + 1.0, (rows_f / c).floor() + 1.0)
    };
    while {
        let (gc, gr) = grid_dims(low);
        gc * gr > SSC_MAX_GRID_CELLS as f64 && low < i64::MAX
    } {
        low = low.saturating_mul(2);
    }
    high = high.max(low);

    let mut grid: Vec<bool> = Vec::new();
    let mut result: Vec<usize> = Vec::with_capacity(len);
    let mut prev_width = -1_i64;
    let mut best: Vec<usize> = Vec::new();
    let mut best_width = 0_i64;
    // The search range halves every step; the cap only guards against surprises.
    for _ in 0..128 {
        let width = low + (high - low) / 2;
        if width == prev_width || low > high {
            break;
        }
        let c = width as f64 / 2.0;
        let (gc, gr) = grid_dims(width);
        // Both fit: width >= low, and low's grid has at most SSC_MAX_GRID_CELLS cells.
        let (gc, gr) = (gc as usize, gr as usize);
        let cells = gc.saturating_mul(gr).min(SSC_MAX_GRID_CELLS);
        if grid.len() < cells {
            grid.resize(cells, false);
        }
        let Some(grid) = grid.get_mut(..cells) else {
            break;
        };
        grid.fill(false);
        result.clear();
        let max_col = gc.saturating_sub(1);
        let max_row = gr.saturating_sub(1);
        for (rank, p) in pts.iter().enumerate() {
            // `as` saturates and maps NaN to 0; then clamp onto the grid.
            let col = ((f64::from(p[0]) / c).floor() as i64).clamp(0, max_col as i64) as usize;
            let row = ((f64::from(p[1]) / c).floor() as i64).clamp(0, max_row as i64) as usize;
            if grid.get(row * gc + col).copied().unwrap_or(true) {
                continue;
            }
            result.push(rank);
            // floor(width / c) == 2: cover two cells around.
            let r0 = row.saturating_sub(2);
            let r1 = (row + 2).min(max_row);
            let c0 = col.saturating_sub(2);
            let c1 = (col + 2).min(max_col);
            for rr in r0..=r1 {
                if let Some(line) = grid.get_mut(rr * gc + c0..=rr * gc + c1) {
                    line.fill(true);
                }
            }
        }
        let kept = result.len() as f64;
        if kept >= k {
            // Remember the widest grid that still keeps at least n.
            if best_width < width {
                best_width = width;
                best.clone_from(&result);
            }
            // Stop within the tolerance, but only once the grid has removed
            // something: keeping every candidate would just be top-N.
            if kept <= k_max && result.len() < len {
                break;
            }
            low = width.saturating_add(1);
        } else {
            high = width.saturating_sub(1);
        }
        prev_width = width;
    }
    if best_width > 0 {
        std::mem::swap(&mut result, &mut best);
    }

    result.truncate(n);
    if result.len() < n {
        let mut kept = vec![false; len];
        for &r in &result {
            if let Some(k) = kept.get_mut(r) {
                *k = true;
            }
        }
        for (rank, &was_kept) in kept.iter().enumerate() {
            if result.len() >= n {
                break;
            }
            if !was_kept {
                result.push(rank);
            }
        }
    }
    result
        .into_iter()
        .filter_map(|r| order.get(r).copied())
        .collect()
}

/// Selects up to `n` keypoints from `candidates` with `method`, in an image of
/// `width` × `height` pixels: [`AnmsMethod::None`] → [`select_top_n`],
/// [`AnmsMethod::Kdtree`] → [`anms_kdtree`], [`AnmsMethod::Ssc`] →
/// [`anms_ssc`] with tolerance [`SSC_TOLERANCE`] and the image size as its grid.
///
/// Returns `min(n, candidates.len())` indices into `candidates`.
pub fn select(
    method: AnmsMethod,
    candidates: &[Candidate],
    n: usize,
    width: usize,
    height: usize,
) -> Vec<usize> {
    match method {
        AnmsMethod::None => select_top_n(candidates, n),
        AnmsMethod::Kdtree => anms_kdtree(candidates, n),
        AnmsMethod::Ssc => anms_ssc(candidates, n, SSC_TOLERANCE, width, height),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn c(x: f32, y: f32, score: f32) -> Candidate {
        Candidate { x, y, score }
    }

    /// Deterministic xorshift generator for the fixed-input tests.
    struct Rng(u64);
    impl Rng {
        fn next_u32(&mut self) -> u32 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 32) as u32
        }
        fn unit(&mut self) -> f32 {
            (self.next_u32() >> 8) as f32 / (1u32 << 24) as f32
        }
    }

    fn check_indices(out: &[usize], len: usize, n: usize) {
        assert_eq!(out.len(), n.min(len));
        let mut seen = vec![false; len];
        for &i in out {
            assert!(i < len, "index {i} out of range {len}");
            assert!(!seen[i], "duplicate index {i}");
            seen[i] = true;
        }
    }

    fn strongest(cands: &[Candidate]) -> Option<usize> {
        strength_order(cands).first().copied()
    }

    fn all_methods(cands: &[Candidate], n: usize) -> [Vec<usize>; 4] {
        [
            select_top_n(cands, n),
            anms_kdtree(cands, n),
            anms_brute_force(cands, n),
            anms_ssc(cands, n, 0.1, 64, 48),
        ]
    }

    fn grid_candidates() -> impl Strategy<Value = Vec<Candidate>> {
        prop::collection::vec(
            (0u8..12, 0u8..12, 0u8..20).prop_map(|(x, y, s)| c(x as f32, y as f32, s as f32)),
            0..400,
        )
    }

    fn continuous_candidates() -> impl Strategy<Value = Vec<Candidate>> {
        prop::collection::vec(
            (0.0f32..640.0, 0.0f32..480.0, -1.0f32..1.0).prop_map(|(x, y, s)| c(x, y, s)),
            0..400,
        )
    }

    /// Rows and columns of points sharing a coordinate: the kd-tree's worst case.
    fn line_candidates() -> impl Strategy<Value = Vec<Candidate>> {
        prop::collection::vec(
            (any::<bool>(), 0u8..4, 0u16..400, 0u8..8).prop_map(|(vertical, line, t, s)| {
                let along = t as f32 * 0.25;
                let at = line as f32 * 7.0;
                if vertical {
                    c(at, along, s as f32)
                } else {
                    c(along, at, s as f32)
                }
            }),
            0..1200,
        )
    }

    fn wild_f32() -> impl Strategy<Value = f32> {
        prop_oneof![
            4 => -50.0f32..50.0,
            1 => Just(f32::NAN),
            1 => Just(f32::INFINITY),
            1 => Just(f32::NEG_INFINITY),
            1 => Just(-0.0f32),
            1 => Just(1.0e30f32),
            1 => any::<f32>(),
        ]
    }

    fn wild_candidates() -> impl Strategy<Value = Vec<Candidate>> {
        prop::collection::vec(
            (wild_f32(), wild_f32(), wild_f32()).prop_map(|(x, y, s)| c(x, y, s)),
            0..200,
        )
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        #[test]
        fn kdtree_equals_brute_force_grid(cands in grid_candidates(), n in 0usize..450) {
            prop_assert_eq!(anms_kdtree(&cands, n), anms_brute_force(&cands, n));
        }

        #[test]
        fn kdtree_equals_brute_force_continuous(cands in continuous_candidates(), n in 0usize..450) {
            prop_assert_eq!(anms_kdtree(&cands, n), anms_brute_force(&cands, n));
        }

        #[test]
        fn kdtree_equals_brute_force_lines(cands in line_candidates(), n in 0usize..1300) {
            prop_assert_eq!(anms_kdtree(&cands, n), anms_brute_force(&cands, n));
        }

        #[test]
        fn kdtree_equals_brute_force_wild(cands in wild_candidates(), n in 0usize..250) {
            prop_assert_eq!(anms_kdtree(&cands, n), anms_brute_force(&cands, n));
        }

        #[test]
        fn sizes_ranges_and_strongest(cands in grid_candidates(), n in 0usize..450) {
            let strongest = strongest(&cands);
            for out in all_methods(&cands, n) {
                check_indices(&out, cands.len(), n);
                if n >= 1 {
                    prop_assert_eq!(out.first().copied(), strongest);
                }
            }
        }

        #[test]
        fn wild_inputs_are_handled(cands in wild_candidates(), n in 0usize..250) {
            let strongest = strongest(&cands);
            for out in all_methods(&cands, n) {
                check_indices(&out, cands.len(), n);
            }
            if n >= 1 {
                prop_assert_eq!(select_top_n(&cands, n).first().copied(), strongest);
                prop_assert_eq!(anms_ssc(&cands, n, 0.1, 64, 48).first().copied(), strongest);
            }
        }

        #[test]
        fn ssc_odd_parameters(
            cands in continuous_candidates(),
            n in 0usize..450,
            tol in wild_f32(),
            cols in prop_oneof![Just(0usize), 1usize..2000, Just(usize::MAX)],
            rows in prop_oneof![Just(0usize), 1usize..2000, Just(usize::MAX)],
        ) {
            let out = anms_ssc(&cands, n, tol, cols, rows);
            check_indices(&out, cands.len(), n);
            if n >= 1 {
                prop_assert_eq!(out.first().copied(), strongest(&cands));
            }
        }

        #[test]
        fn top_n_is_descending_and_stable(cands in grid_candidates(), n in 0usize..450) {
            let out = select_top_n(&cands, n);
            prop_assert_eq!(&out[..], &strength_order(&cands)[..out.len()]);
            for w in out.windows(2) {
                let (a, b) = (cands[w[0]].score, cands[w[1]].score);
                prop_assert!(a > b || (a == b && w[0] < w[1]));
            }
        }

        #[test]
        fn anms_radii_descending(cands in continuous_candidates(), n in 0usize..450) {
            // Recompute each output's radius and check the order.
            let order = strength_order(&cands);
            let mut rank = vec![0; cands.len()];
            for (r, &i) in order.iter().enumerate() {
                rank[i] = r;
            }
            let radius = |i: usize| {
                order[..rank[i]]
                    .iter()
                    .map(|&j| sq_dist([cands[i].x, cands[i].y], [cands[j].x, cands[j].y]))
                    .fold(f32::INFINITY, f32::min)
            };
            let out = anms_kdtree(&cands, n);
            for w in out.windows(2) {
                let (ra, rb) = (radius(w[0]), radius(w[1]));
                prop_assert!(ra > rb || (ra == rb && rank[w[0]] < rank[w[1]]));
            }
        }
    }

    #[test]
    fn empty_and_zero() {
        let empty: [Candidate; 0] = [];
        for method in [AnmsMethod::None, AnmsMethod::Kdtree, AnmsMethod::Ssc] {
            assert!(select(method, &empty, 10, 640, 480).is_empty());
        }
        let one = [c(1.0, 2.0, 0.5)];
        for out in all_methods(&one, 0) {
            assert!(out.is_empty());
        }
        for out in all_methods(&one, 5) {
            assert_eq!(out, vec![0]);
        }
    }

    #[test]
    fn nan_scores_are_weakest() {
        let cands = [
            c(0.0, 0.0, f32::NAN),
            c(10.0, 0.0, f32::NEG_INFINITY),
            c(20.0, 0.0, 1.0),
            c(30.0, 0.0, f32::NAN),
            c(40.0, 0.0, 1.0),
        ];
        assert_eq!(select_top_n(&cands, 5), vec![2, 4, 1, 0, 3]);
        assert_eq!(select_top_n(&cands, 2), vec![2, 4]);
        assert_eq!(anms_kdtree(&cands, 1), vec![2]);
        assert_eq!(anms_ssc(&cands, 1, 0.1, 64, 8), vec![2]);
        let all_nan = [c(0.0, 0.0, f32::NAN), c(5.0, 5.0, f32::NAN)];
        for out in all_methods(&all_nan, 2) {
            check_indices(&out, 2, 2);
            assert_eq!(out[0], 0);
        }
    }

    #[test]
    fn paper_anms_small_example() {
        // Strength order: 0, 1, 2, 3. r: inf, 10, 1 (to 1), 5 (to 0).
        let cands = [
            c(0.0, 0.0, 4.0),
            c(10.0, 0.0, 3.0),
            c(11.0, 0.0, 2.0),
            c(0.0, 5.0, 1.0),
        ];
        assert_eq!(anms_kdtree(&cands, 4), vec![0, 1, 3, 2]);
        assert_eq!(anms_brute_force(&cands, 4), vec![0, 1, 3, 2]);
        assert_eq!(anms_kdtree(&cands, 2), vec![0, 1]);
    }

    #[test]
    fn radii_agree_on_lines() {
        let mut cands = Vec::new();
        let mut rng = Rng(7);
        for i in 0..5000 {
            cands.push(c(3.0, 4.0, rng.unit() + (i % 3) as f32));
        }
        for i in 0..2000 {
            cands.push(c(100.0, i as f32 * 0.5, rng.unit()));
            cands.push(c(i as f32 * 0.25, 200.0, rng.unit()));
        }
        let order = strength_order(&cands);
        assert_eq!(
            radii_indexed(&cands, &order),
            radii_brute_force(&cands, &order)
        );
    }

    #[test]
    fn many_duplicates_and_collinear_points() {
        // 5000 identical positions, a 2000-point vertical line and a 2000-point
        // horizontal line: buckets full of equal coordinates.
        let mut cands = Vec::new();
        let mut rng = Rng(7);
        for i in 0..5000 {
            cands.push(c(3.0, 4.0, rng.unit() + (i % 3) as f32));
        }
        for i in 0..2000 {
            cands.push(c(100.0, i as f32 * 0.5, rng.unit()));
            cands.push(c(i as f32 * 0.25, 200.0, rng.unit()));
        }
        for n in [0, 1, 10, 500, 3000, 20000] {
            let kd = anms_kdtree(&cands, n);
            check_indices(&kd, cands.len(), n);
            assert_eq!(kd, anms_brute_force(&cands, n));
            check_indices(&anms_ssc(&cands, n, 0.1, 1226, 370), cands.len(), n);
        }
    }

    fn cells_covered(cands: &[Candidate], idx: &[usize]) -> usize {
        let mut cells: Vec<(i32, i32)> = idx
            .iter()
            .map(|&i| ((cands[i].x / 32.0) as i32, (cands[i].y / 32.0) as i32))
            .collect();
        cells.sort_unstable();
        cells.dedup();
        cells.len()
    }

    #[test]
    fn anms_spreads_better_than_top_n() {
        // A dense strong cluster plus a sparse, weaker uniform background.
        let (w, h) = (640.0, 480.0);
        let mut rng = Rng(42);
        let mut cands = Vec::new();
        for _ in 0..2000 {
            let x = 300.0 + rng.unit() * 60.0;
            let y = 200.0 + rng.unit() * 60.0;
            cands.push(c(x, y, 0.5 + rng.unit() * 0.5));
        }
        for _ in 0..1000 {
            cands.push(c(rng.unit() * w, rng.unit() * h, rng.unit() * 0.5));
        }
        let n = 300;
        let top = cells_covered(&cands, &select_top_n(&cands, n));
        let kd = cells_covered(&cands, &anms_kdtree(&cands, n));
        let ssc = cells_covered(&cands, &anms_ssc(&cands, n, 0.1, 640, 480));
        assert!(top <= 9, "top-N covered {top} cells");
        assert!(
            kd > 3 * top && kd > 150,
            "kdtree covered {kd} vs top-N {top}"
        );
        assert!(
            ssc > 3 * top && ssc > 150,
            "ssc covered {ssc} vs top-N {top}"
        );
    }

    #[test]
    fn ssc_hits_target_on_uniform_input() {
        let mut rng = Rng(3);
        let cands: Vec<Candidate> = (0..10_000)
            .map(|_| c(rng.unit() * 1226.0, rng.unit() * 370.0, rng.unit()))
            .collect();
        let out = anms_ssc(&cands, 1000, 0.1, 1226, 370);
        check_indices(&out, cands.len(), 1000);
        let dispatched = select(AnmsMethod::Ssc, &cands, 1000, 1226, 370);
        assert_eq!(out, dispatched);
        assert_eq!(
            select(AnmsMethod::Kdtree, &cands, 1000, 1226, 370),
            anms_kdtree(&cands, 1000)
        );
        assert_eq!(
            select(AnmsMethod::None, &cands, 1000, 1226, 370),
            select_top_n(&cands, 1000)
        );
    }
}
