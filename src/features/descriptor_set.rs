//! Descriptor blocks of either kind: SuperPoint's unit-L2 float rows or ORB's
//! 256-bit binary rows, with one distance for both (L2 or Hamming).

/// Bytes in one ORB (rBRIEF) descriptor: 256 bits.
pub const ORB_DESCRIPTOR_BYTES: usize = 32;

/// One binary ORB descriptor.
pub type BinaryDescriptor = [u8; ORB_DESCRIPTOR_BYTES];

/// Which metric a descriptor kind uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DescriptorKind {
    /// Float rows of the given length, compared by L2 distance.
    Float {
        /// Floats per row.
        dim: usize,
    },
    /// 32-byte binary rows, compared by Hamming distance.
    Binary,
}

impl std::fmt::Display for DescriptorKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            DescriptorKind::Float { dim } => write!(f, "float[{dim}] (L2)"),
            DescriptorKind::Binary => write!(f, "binary[32 bytes] (Hamming)"),
        }
    }
}

/// The distance between two descriptors of the same kind.
pub trait DescriptorDistance {
    /// L2 distance for float rows, Hamming distance (as f32) for binary rows.
    fn distance_to(&self, other: &Self) -> f32;
}

impl DescriptorDistance for [f32] {
    fn distance_to(&self, other: &Self) -> f32 {
        // Eight partial sums so that the compiler can vectorise the loop.
        let mut acc = [0.0f32; 8];
        let (a_chunks, b_chunks) = (self.chunks_exact(8), other.chunks_exact(8));
        let (a_rest, b_rest) = (a_chunks.remainder(), b_chunks.remainder());
        for (a, b) in a_chunks.zip(b_chunks) {
            for k in 0..8 {
                let d = a[k] - b[k];
                acc[k] += d * d;
            }
        }
        let tail: f32 = a_rest
            .iter()
            .zip(b_rest)
            .map(|(a, b)| (a - b) * (a - b))
            .sum();
        (acc.iter().sum::<f32>() + tail).sqrt()
    }
}

impl DescriptorDistance for BinaryDescriptor {
    fn distance_to(&self, other: &Self) -> f32 {
        // Four 64-bit words, as ORB-SLAM3's DescriptorDistance counts bits on words.
        let mut bits = 0u32;
        for (a, b) in self.chunks_exact(8).zip(other.chunks_exact(8)) {
            let mut wa = [0u8; 8];
            let mut wb = [0u8; 8];
            wa.copy_from_slice(a);
            wb.copy_from_slice(b);
            bits += (u64::from_le_bytes(wa) ^ u64::from_le_bytes(wb)).count_ones();
        }
        bits as f32
    }
}

/// A borrowed descriptor of either kind.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DescriptorRef<'a> {
    /// A float row.
    Float(&'a [f32]),
    /// A binary row.
    Binary(&'a BinaryDescriptor),
}

impl DescriptorRef<'_> {
    /// The kind of this descriptor.
    pub fn kind(&self) -> DescriptorKind {
        match self {
            DescriptorRef::Float(row) => DescriptorKind::Float { dim: row.len() },
            DescriptorRef::Binary(_) => DescriptorKind::Binary,
        }
    }

    /// The distance to `other`, or `None` when the kinds (or float lengths) differ.
    pub fn distance(&self, other: &DescriptorRef<'_>) -> Option<f32> {
        match (self, other) {
            (DescriptorRef::Float(a), DescriptorRef::Float(b)) if a.len() == b.len() => {
                Some(a.distance_to(b))
            }
            (DescriptorRef::Binary(a), DescriptorRef::Binary(b)) => Some(a.distance_to(b)),
            _ => None,
        }
    }
}

/// An owned block of descriptors, one row per keypoint.
#[derive(Clone, Debug, PartialEq)]
pub enum DescriptorSet {
    /// Row-major float rows of `dim` values each (SuperPoint: 256, unit L2 norm).
    Float {
        /// Floats per row.
        dim: usize,
        /// `len * dim` values.
        data: Vec<f32>,
    },
    /// ORB's 256-bit rows.
    Binary {
        /// One row per keypoint.
        data: Vec<BinaryDescriptor>,
    },
}

impl DescriptorSet {
    /// The kind of the rows.
    pub fn kind(&self) -> DescriptorKind {
        match self {
            DescriptorSet::Float { dim, .. } => DescriptorKind::Float { dim: *dim },
            DescriptorSet::Binary { .. } => DescriptorKind::Binary,
        }
    }

    /// Number of rows (0 for a float set with `dim` 0).
    pub fn len(&self) -> usize {
        match self {
            DescriptorSet::Float { dim, data } => data.len().checked_div(*dim).unwrap_or(0),
            DescriptorSet::Binary { data } => data.len(),
        }
    }

    /// True when there is no row.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Row `i`, or `None` when out of range.
    pub fn row(&self, i: usize) -> Option<DescriptorRef<'_>> {
        match self {
            DescriptorSet::Float { dim, data } => {
                let start = i.checked_mul(*dim)?;
                data.get(start..start.checked_add(*dim)?)
                    .map(DescriptorRef::Float)
            }
            DescriptorSet::Binary { data } => data.get(i).map(DescriptorRef::Binary),
        }
    }

    /// The distance between row `i` of `self` and row `j` of `other`; `None`
    /// when a row is out of range or the kinds differ.
    pub fn distance(&self, i: usize, other: &DescriptorSet, j: usize) -> Option<f32> {
        self.row(i)?.distance(&other.row(j)?)
    }

    /// Keeps only the rows whose index `keep` returns true for, in order.
    pub fn retain_rows(&mut self, mut keep: impl FnMut(usize) -> bool) {
        match self {
            DescriptorSet::Float { dim, data } => {
                let dim = *dim;
                if dim == 0 {
                    return;
                }
                let mut out = Vec::with_capacity(data.len());
                for (i, row) in data.chunks_exact(dim).enumerate() {
                    if keep(i) {
                        out.extend_from_slice(row);
                    }
                }
                *data = out;
            }
            DescriptorSet::Binary { data } => {
                let mut i = 0;
                data.retain(|_| {
                    let k = keep(i);
                    i += 1;
                    k
                });
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hamming_counts_differing_bits() {
        let a = [0u8; 32];
        let mut b = [0u8; 32];
        b[0] = 0b1011;
        b[31] = 0xff;
        assert_eq!(a.distance_to(&b), 11.0);
        assert_eq!(b.distance_to(&b), 0.0);
    }

    #[test]
    fn rows_and_mixed_kinds() {
        let f = DescriptorSet::Float {
            dim: 2,
            data: vec![1.0, 0.0, 0.0, 1.0],
        };
        let b = DescriptorSet::Binary {
            data: vec![[0u8; 32]],
        };
        assert_eq!(f.len(), 2);
        assert!((f.distance(0, &f, 1).unwrap_or(0.0) - 2f32.sqrt()).abs() < 1e-6);
        assert_eq!(f.distance(0, &b, 0), None);
        assert_eq!(f.row(2), None);
        let mut g = f.clone();
        g.retain_rows(|i| i == 1);
        assert_eq!(g.row(0), Some(DescriptorRef::Float(&[0.0, 1.0])));
    }
}
