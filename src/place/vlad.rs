//! VLAD (Jégou et al. 2010, with the normalisations of Arandjelović and
//! Zisserman, "All about VLAD", 2013) over a k-means codebook, and optional
//! PCA whitening.
//!
//! For a frame with local descriptors `x`: each `x` is assigned to its
//! nearest centre `c` (squared L2, the lowest index among equals, as
//! [`kmeans`](super::kmeans::kmeans) assigns), and the residuals `x − c` are
//! summed per centre (in `f64`, so the order of the descriptors changes
//! nothing but rounding in the last bit). The `k` blocks of `dim` values are
//! then
//! 1. intra-normalised: each block scaled to unit L2 norm (an empty block stays zero);
//! 2. power-normalised: each value replaced by `sign(v)·sqrt(|v|)`;
//! 3. L2-normalised as a whole.
//!
//! With [`Whitening`], the result is centred, projected on the top principal
//! directions of training VLADs scaled by `1/sqrt(λ + eps)`, and L2-normalised
//! again.
//!
//! A frame without descriptors is [`PlaceError::NoDescriptors`]; a frame
//! whose every descriptor lies exactly on its centre (all residuals zero)
//! gives the same error, since no unit vector describes it.

use nalgebra::DMatrix;

use super::global_descriptor::{dot, l2_normalise};
use super::{ClusterMetric, DescriptorRows, GlobalDescriptor, L2Float, PlaceError};

/// The codebook size used when none is given.
pub const DEFAULT_K: usize = 64;

/// VLAD over a codebook of `k` centres of `dim` values: a `k · dim` global
/// descriptor, or the whitening's output size.
#[derive(Debug, Clone, PartialEq)]
pub struct Vlad {
    centres: DescriptorRows<f32>,
    whitening: Option<Whitening>,
}

impl Vlad {
    /// VLAD over `centres` (at least one), without whitening. Every value
    /// must be finite.
    pub fn new(centres: DescriptorRows<f32>) -> Result<Self, PlaceError> {
        if centres.is_empty() {
            return Err(PlaceError::invalid("k", 0, "at least one centre"));
        }
        if centres.as_flat().iter().any(|v| !v.is_finite()) {
            return Err(PlaceError::Inconsistent {
                reason: "a codebook centre has a non-finite value".into(),
            });
        }
        Ok(Self {
            centres,
            whitening: None,
        })
    }

    /// The same VLAD, whitened by `whitening`, whose input must be
    /// [`raw_dim`](Self::raw_dim) long.
    pub fn with_whitening(mut self, whitening: Whitening) -> Result<Self, PlaceError> {
        if whitening.input_dim() != self.raw_dim() {
            return Err(PlaceError::RowLength {
                expected: self.raw_dim(),
                actual: whitening.input_dim(),
            });
        }
        self.whitening = Some(whitening);
        Ok(self)
    }

    /// The codebook's centres.
    pub fn centres(&self) -> &DescriptorRows<f32> {
        &self.centres
    }

    /// The whitening, if any.
    pub fn whitening(&self) -> Option<&Whitening> {
        self.whitening.as_ref()
    }

    /// Number of centres.
    pub fn k(&self) -> usize {
        self.centres.len()
    }

    /// Length of the VLAD before whitening: `k · local_dim`.
    pub fn raw_dim(&self) -> usize {
        self.centres.len() * self.centres.row_len()
    }

    /// The normalised VLAD of `flat` (rows of [`local_dim`](GlobalDescriptor::local_dim)
    /// values), before whitening: what whitening is fitted on.
    pub fn raw(&self, flat: &[f32]) -> Result<Vec<f32>, PlaceError> {
        let d = self.centres.row_len();
        if !flat.len().is_multiple_of(d) {
            return Err(PlaceError::Inconsistent {
                reason: format!(
                    "{} values are not a whole number of {d}-value descriptors",
                    flat.len()
                ),
            });
        }
        if flat.is_empty() {
            return Err(PlaceError::NoDescriptors {
                reason: "VLAD of a frame without local descriptors".into(),
            });
        }
        if flat.iter().any(|v| !v.is_finite()) {
            return Err(PlaceError::Inconsistent {
                reason: "a local descriptor has a non-finite value".into(),
            });
        }
        let metric = L2Float { dim: d };
        let mut sums = vec![0.0f64; self.raw_dim()];
        for x in flat.chunks_exact(d) {
            let c = nearest_centre(&metric, x, &self.centres);
            let block = &mut sums[c * d..(c + 1) * d];
            for ((s, &v), &m) in block.iter_mut().zip(x).zip(self.centres.row(c)) {
                *s += f64::from(v) - f64::from(m);
            }
        }
        for block in sums.chunks_exact_mut(d) {
            let norm = block.iter().map(|v| v * v).sum::<f64>().sqrt();
            if norm > 0.0 {
                block.iter_mut().for_each(|v| *v /= norm);
            }
        }
        let mut out: Vec<f32> = sums
            .iter()
            .map(|&v| (v.signum() * v.abs().sqrt()) as f32)
            .collect();
        if !l2_normalise(&mut out) {
            return Err(PlaceError::NoDescriptors {
                reason: "every local descriptor lies on its centre: the VLAD is zero".into(),
            });
        }
        Ok(out)
    }
}

impl GlobalDescriptor for Vlad {
    fn local_dim(&self) -> usize {
        self.centres.row_len()
    }

    fn dim(&self) -> usize {
        self.whitening
            .as_ref()
            .map_or(self.raw_dim(), Whitening::output_dim)
    }

    fn compute_flat(&self, flat: &[f32]) -> Result<Vec<f32>, PlaceError> {
        let raw = self.raw(flat)?;
        match &self.whitening {
            None => Ok(raw),
            Some(w) => w.apply(&raw),
        }
    }
}

/// The index of the centre nearest to `x` (squared L2; the lowest index among equals).
pub(crate) fn nearest_centre(metric: &L2Float, x: &[f32], centres: &DescriptorRows<f32>) -> usize {
    let mut best = 0;
    let mut best_d = f32::INFINITY;
    for (c, centre) in centres.iter().enumerate() {
        let d = metric.distance(x, centre);
        if d < best_d {
            best_d = d;
            best = c;
        }
    }
    best
}

/// PCA whitening: `y = P (x − mean)`, then L2-normalised, where the rows of
/// `P` are the top principal directions of training vectors, each scaled by
/// `1 / sqrt(λ + eps)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Whitening {
    mean: Vec<f32>,
    /// `output_dim` rows of `input_dim` values.
    projection: DescriptorRows<f32>,
}

impl Whitening {
    /// A whitening from its parts: `mean` (the input length) and the
    /// projection's rows (each as long as `mean`, at least one).
    pub fn from_parts(mean: Vec<f32>, projection: DescriptorRows<f32>) -> Result<Self, PlaceError> {
        if projection.row_len() != mean.len() {
            return Err(PlaceError::RowLength {
                expected: mean.len(),
                actual: projection.row_len(),
            });
        }
        if projection.is_empty() {
            return Err(PlaceError::invalid("whitening size", 0, "at least 1"));
        }
        if mean
            .iter()
            .chain(projection.as_flat())
            .any(|v| !v.is_finite())
        {
            return Err(PlaceError::Inconsistent {
                reason: "the whitening has a non-finite value".into(),
            });
        }
        Ok(Self { mean, projection })
    }

    /// Fits a whitening to `output_dim` values on `training` (one vector per
    /// row). The principal directions come from nalgebra's symmetric
    /// eigen-decomposition of the `D × D` covariance, or, when there are
    /// fewer vectors `N` than values `D` (the usual case for VLAD), of the
    /// `N × N` Gram matrix of the centred vectors (the same non-zero
    /// eigenvalues; a direction is `Xᵀu / sqrt(N λ)`). `output_dim` must be
    /// at most `min(N − 1, D)`, the rank of centred data. Each direction's
    /// sign is fixed so that its largest-magnitude value is positive, so the
    /// result does not depend on the eigen-solver's sign choice.
    pub fn fit(
        training: &DescriptorRows<f32>,
        output_dim: usize,
        eps: f64,
    ) -> Result<Self, PlaceError> {
        let (n, d) = (training.len(), training.row_len());
        if n < 2 {
            return Err(PlaceError::NoDescriptors {
                reason: format!("PCA whitening needs at least 2 training vectors, got {n}"),
            });
        }
        let rank = (n - 1).min(d);
        if output_dim == 0 || output_dim > rank {
            return Err(PlaceError::InvalidParameter {
                name: "whitening size",
                value: output_dim.to_string(),
                expected: "between 1 and min(training vectors - 1, input length)",
            });
        }
        if !(eps.is_finite() && eps >= 0.0) {
            return Err(PlaceError::invalid("whitening eps", eps, "a number >= 0"));
        }
        let mut mean = vec![0.0f64; d];
        for row in training.iter() {
            for (m, &v) in mean.iter_mut().zip(row) {
                *m += f64::from(v);
            }
        }
        mean.iter_mut().for_each(|m| *m /= n as f64);
        let centred = DMatrix::<f64>::from_fn(n, d, |i, j| f64::from(training.row(i)[j]) - mean[j]);
        let (values, directions) = if n <= d {
            let gram = &centred * centred.transpose() / n as f64;
            let eig = gram.symmetric_eigen();
            let order = descending(eig.eigenvalues.as_slice());
            let mut dirs = DMatrix::<f64>::zeros(d, output_dim);
            let mut vals = Vec::with_capacity(output_dim);
            for (col, &i) in order.iter().take(output_dim).enumerate() {
                let lambda = eig.eigenvalues[i].max(0.0);
                let u = eig.eigenvectors.column(i);
                let e = centred.transpose() * u;
                let scale = (n as f64 * lambda).sqrt();
                let e = if scale > 0.0 { e / scale } else { e };
                dirs.set_column(col, &e);
                vals.push(lambda);
            }
            (vals, dirs)
        } else {
            let cov = centred.transpose() * &centred / n as f64;
            let eig = cov.symmetric_eigen();
            let order = descending(eig.eigenvalues.as_slice());
            let mut dirs = DMatrix::<f64>::zeros(d, output_dim);
            let mut vals = Vec::with_capacity(output_dim);
            for (col, &i) in order.iter().take(output_dim).enumerate() {
                dirs.set_column(col, &eig.eigenvectors.column(i));
                vals.push(eig.eigenvalues[i].max(0.0));
            }
            (vals, dirs)
        };
        let mut projection = Vec::with_capacity(output_dim * d);
        for (col, lambda) in values.iter().enumerate() {
            let e = directions.column(col);
            let pivot = e
                .iter()
                .enumerate()
                .fold((0, 0.0f64), |best, (i, &v)| {
                    if v.abs() > best.1 {
                        (i, v.abs())
                    } else {
                        best
                    }
                })
                .0;
            let sign = if e[pivot] < 0.0 { -1.0 } else { 1.0 };
            let scale = sign / (lambda + eps).sqrt();
            if !scale.is_finite() {
                return Err(PlaceError::invalid(
                    "whitening eps",
                    eps,
                    "a number > 0 when the training vectors have zero-variance directions",
                ));
            }
            projection.extend(e.iter().map(|&v| (v * scale) as f32));
        }
        Self::from_parts(
            mean.iter().map(|&m| m as f32).collect(),
            DescriptorRows::from_flat(d, projection)?,
        )
    }

    /// Length of the vectors it takes.
    pub fn input_dim(&self) -> usize {
        self.mean.len()
    }

    /// Length of the vectors it gives.
    pub fn output_dim(&self) -> usize {
        self.projection.len()
    }

    /// The training mean.
    pub fn mean(&self) -> &[f32] {
        &self.mean
    }

    /// The projection, one scaled principal direction per row.
    pub fn projection(&self) -> &DescriptorRows<f32> {
        &self.projection
    }

    /// The whitened, L2-normalised `x` (of [`input_dim`](Self::input_dim) values).
    pub fn apply(&self, x: &[f32]) -> Result<Vec<f32>, PlaceError> {
        if x.len() != self.input_dim() {
            return Err(PlaceError::RowLength {
                expected: self.input_dim(),
                actual: x.len(),
            });
        }
        let centred: Vec<f32> = x.iter().zip(&self.mean).map(|(v, m)| v - m).collect();
        let mut out: Vec<f32> = self.projection.iter().map(|p| dot(p, &centred)).collect();
        if !l2_normalise(&mut out) {
            return Err(PlaceError::NoDescriptors {
                reason: "the whitened descriptor is zero (the input equals the training mean)"
                    .into(),
            });
        }
        Ok(out)
    }
}

/// Indices of `values`, largest first (the lower index first among equals).
fn descending(values: &[f64]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..values.len()).collect();
    order.sort_by(|&a, &b| values[b].total_cmp(&values[a]).then(a.cmp(&b)));
    order
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::place::SeededRng;

    fn random_rows(n: usize, d: usize, seed: u64) -> DescriptorRows<f32> {
        let mut rng = SeededRng::new(seed);
        let data = (0..n * d).map(|_| rng.next_unit() as f32 - 0.5).collect();
        DescriptorRows::from_flat(d, data).unwrap()
    }

    /// VLAD written out plainly: per-centre residual lists, then the three
    /// normalisations, all in `f64`.
    fn brute_force_vlad(centres: &DescriptorRows<f32>, rows: &DescriptorRows<f32>) -> Vec<f32> {
        let (k, d) = (centres.len(), centres.row_len());
        let mut v = vec![vec![0.0f64; d]; k];
        for x in rows.iter() {
            let dists: Vec<f64> = centres
                .iter()
                .map(|c| c.iter().zip(x).map(|(a, b)| f64::from(a - b).powi(2)).sum())
                .collect();
            let mut best = 0;
            for c in 1..k {
                if dists[c] < dists[best] {
                    best = c;
                }
            }
            for j in 0..d {
                v[best][j] += f64::from(x[j]) - f64::from(centres.row(best)[j]);
            }
        }
        let mut flat = Vec::new();
        for block in &v {
            let n: f64 = block.iter().map(|a| a * a).sum::<f64>().sqrt();
            flat.extend(block.iter().map(|a| if n > 0.0 { a / n } else { 0.0 }));
        }
        let flat: Vec<f64> = flat.iter().map(|a| a.signum() * a.abs().sqrt()).collect();
        let n: f64 = flat.iter().map(|a| a * a).sum::<f64>().sqrt();
        flat.iter().map(|a| (a / n) as f32).collect()
    }

    #[test]
    fn matches_a_brute_force_reference_and_is_unit_norm() {
        for seed in 0..5 {
            let centres = random_rows(6, 8, seed);
            let rows = random_rows(40, 8, 100 + seed);
            let vlad = Vlad::new(centres.clone()).unwrap();
            let v = vlad.compute(&rows).unwrap();
            assert_eq!(v.len(), vlad.dim());
            assert_eq!(v.len(), 48);
            let norm: f32 = v.iter().map(|x| x * x).sum::<f32>().sqrt();
            assert!((norm - 1.0).abs() < 1e-5, "norm {norm}");
            let reference = brute_force_vlad(&centres, &rows);
            for (a, b) in v.iter().zip(&reference) {
                assert!((a - b).abs() < 1e-6, "{a} vs {b}");
            }
        }
    }

    #[test]
    fn the_order_of_local_descriptors_does_not_matter() {
        let centres = random_rows(4, 16, 1);
        let rows = random_rows(50, 16, 2);
        let vlad = Vlad::new(centres).unwrap();
        let forward = vlad.compute(&rows).unwrap();
        let reversed: Vec<f32> = rows.iter().rev().flatten().copied().collect();
        let backward = vlad.compute_flat(&reversed).unwrap();
        for (a, b) in forward.iter().zip(&backward) {
            assert!((a - b).abs() <= 1e-7, "{a} vs {b}");
        }
    }

    #[test]
    fn empty_and_bad_input_are_typed_errors() {
        let vlad = Vlad::new(random_rows(3, 4, 1)).unwrap();
        assert!(matches!(
            vlad.compute_flat(&[]),
            Err(PlaceError::NoDescriptors { .. })
        ));
        assert!(matches!(
            vlad.compute_flat(&[0.0; 5]),
            Err(PlaceError::Inconsistent { .. })
        ));
        assert!(matches!(
            vlad.compute(&random_rows(2, 5, 1)),
            Err(PlaceError::RowLength { .. })
        ));
        // Every descriptor on its centre: a zero VLAD is refused.
        let centre = vlad.centres().row(0).to_vec();
        assert!(matches!(
            vlad.compute_flat(&centre),
            Err(PlaceError::NoDescriptors { .. })
        ));
        assert!(Vlad::new(DescriptorRows::new(4).unwrap()).is_err());
    }

    #[test]
    fn whitening_decorrelates_training_data_in_both_branches() {
        // N < D (Gram branch) and N > D (covariance branch).
        for (n, d, out) in [(12, 30, 5), (60, 6, 4)] {
            let training = random_rows(n, d, 7);
            let w = Whitening::fit(&training, out, 0.0).unwrap();
            assert_eq!((w.input_dim(), w.output_dim()), (d, out));
            // Projected (unnormalised) training data has unit variance per
            // output and no correlation between outputs.
            let projected: Vec<Vec<f64>> = training
                .iter()
                .map(|x| {
                    w.projection()
                        .iter()
                        .map(|p| {
                            p.iter()
                                .zip(x.iter().zip(w.mean()))
                                .map(|(a, (v, m))| f64::from(*a) * f64::from(v - m))
                                .sum()
                        })
                        .collect()
                })
                .collect();
            for a in 0..out {
                for b in 0..out {
                    let cov: f64 = projected.iter().map(|y| y[a] * y[b]).sum::<f64>() / n as f64;
                    let want = if a == b { 1.0 } else { 0.0 };
                    assert!((cov - want).abs() < 1e-3, "cov[{a}][{b}] = {cov}");
                }
            }
            let y = w.apply(training.row(0)).unwrap();
            assert!((dot(&y, &y) - 1.0).abs() < 1e-5);
            assert_eq!(Whitening::fit(&training, out, 0.0).unwrap(), w);
        }
        let training = random_rows(5, 30, 1);
        assert!(Whitening::fit(&training, 5, 1e-6).is_err());
        assert!(Whitening::fit(&training, 0, 1e-6).is_err());
    }

    #[test]
    fn whitened_vlad_has_the_whitening_size() {
        let centres = random_rows(4, 8, 3);
        let vlad = Vlad::new(centres).unwrap();
        let mut training = DescriptorRows::new(vlad.raw_dim()).unwrap();
        for seed in 0..20 {
            training
                .push_row(&vlad.raw(random_rows(30, 8, 50 + seed).as_flat()).unwrap())
                .unwrap();
        }
        let w = Whitening::fit(&training, 10, 1e-6).unwrap();
        let vlad = vlad.with_whitening(w).unwrap();
        assert_eq!(vlad.dim(), 10);
        let v = vlad.compute(&random_rows(30, 8, 99)).unwrap();
        assert_eq!(v.len(), 10);
        assert!((dot(&v, &v) - 1.0).abs() < 1e-5);
        let bad = Whitening::fit(&random_rows(5, 3, 1), 2, 1e-6).unwrap();
        assert!(Vlad::new(random_rows(4, 8, 3))
            .unwrap()
            .with_whitening(bad)
            .is_err());
    }
}
