//! The global descriptor of a keyframe: one fixed-length, unit-norm vector
//! computed from a frame's local descriptors, compared by cosine similarity
//! (a dot product). [`Vlad`](super::Vlad) is the one built in; a learned
//! model (a NetVLAD-style ONNX network) can implement the same trait later.

use super::{DescriptorRows, PlaceError};

/// Turns a frame's local descriptors into one global descriptor.
///
/// Implementations return a vector of [`dim`](Self::dim) finite values with
/// unit L2 norm, so that the dot product of two of them is their cosine
/// similarity. A frame without descriptors is an error
/// ([`PlaceError::NoDescriptors`]), never a zero vector.
pub trait GlobalDescriptor: Send + Sync {
    /// Values per local descriptor row accepted (256 for SuperPoint).
    fn local_dim(&self) -> usize;

    /// Length of the global descriptor.
    fn dim(&self) -> usize;

    /// The global descriptor of the rows of `flat`, one local descriptor of
    /// [`local_dim`](Self::local_dim) values after the other.
    fn compute_flat(&self, flat: &[f32]) -> Result<Vec<f32>, PlaceError>;

    /// The global descriptor of `rows`; their row length must be
    /// [`local_dim`](Self::local_dim).
    fn compute(&self, rows: &DescriptorRows<f32>) -> Result<Vec<f32>, PlaceError> {
        if rows.row_len() != self.local_dim() {
            return Err(PlaceError::RowLength {
                expected: self.local_dim(),
                actual: rows.row_len(),
            });
        }
        self.compute_flat(rows.as_flat())
    }
}

/// The dot product of two equally long vectors, in eight partial sums so
/// that the compiler vectorises it (cosine similarity for unit vectors).
pub fn dot(a: &[f32], b: &[f32]) -> f32 {
    let mut acc = [0.0f32; 8];
    let (a_chunks, b_chunks) = (a.chunks_exact(8), b.chunks_exact(8));
    let tail: f32 = a_chunks
        .remainder()
        .iter()
        .zip(b_chunks.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in a_chunks.zip(b_chunks) {
        for k in 0..8 {
            acc[k] += x[k] * y[k];
        }
    }
    acc.iter().sum::<f32>() + tail
}

/// Scales `v` to unit L2 norm (accumulated in `f64`). Returns false, leaving
/// `v` as it is, when its norm is zero or not finite.
pub fn l2_normalise(v: &mut [f32]) -> bool {
    let norm = v
        .iter()
        .map(|&x| f64::from(x) * f64::from(x))
        .sum::<f64>()
        .sqrt();
    if !(norm.is_finite() && norm > 0.0) {
        return false;
    }
    for x in v.iter_mut() {
        *x = (f64::from(*x) / norm) as f32;
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dot_and_normalise() {
        let a: Vec<f32> = (0..19).map(|i| i as f32).collect();
        let brute: f32 = a.iter().map(|x| x * x).sum();
        assert_eq!(dot(&a, &a), brute);
        let mut v = a.clone();
        assert!(l2_normalise(&mut v));
        assert!((dot(&v, &v) - 1.0).abs() < 1e-6);
        let mut zero = vec![0.0f32; 4];
        assert!(!l2_normalise(&mut zero));
        assert_eq!(zero, vec![0.0; 4]);
    }
}
