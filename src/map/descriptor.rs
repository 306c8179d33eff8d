//! A map point's representative descriptor.

use std::sync::Arc;

use crate::features::{DescriptorRef, DescriptorSet};

/// One owned descriptor of either kind.
#[derive(Debug, Clone, PartialEq)]
pub enum PointDescriptor {
    /// A float descriptor (SuperPoint: 256 values, unit L2 norm), shared:
    /// a copy of the point (a loop check's [`Map::excerpt`](super::Map::excerpt))
    /// does not copy its values, and a new representative replaces it whole.
    Float(Arc<[f32]>),
    /// A binary ORB descriptor.
    Binary([u8; 32]),
}

impl PointDescriptor {
    /// Copies row `i` of a descriptor block.
    pub fn from_set(set: &DescriptorSet, i: usize) -> Option<Self> {
        set.row(i).map(|row| Self::from_ref(&row))
    }

    /// Copies a borrowed descriptor.
    pub fn from_ref(row: &DescriptorRef<'_>) -> Self {
        match row {
            DescriptorRef::Float(values) => Self::Float(Arc::from(*values)),
            DescriptorRef::Binary(bits) => Self::Binary(**bits),
        }
    }

    /// Borrows it.
    pub fn as_ref(&self) -> DescriptorRef<'_> {
        match self {
            Self::Float(values) => DescriptorRef::Float(values),
            Self::Binary(bits) => DescriptorRef::Binary(bits),
        }
    }

    /// The distance to another descriptor (L2 or Hamming), `None` when the kinds differ.
    pub fn distance(&self, other: &DescriptorRef<'_>) -> Option<f32> {
        self.as_ref().distance(other)
    }
}

/// The index of the descriptor with the least median distance to the others
/// (ORB-SLAM3's `ComputeDistinctiveDescriptors`, for L2 as for Hamming).
/// Ties go to the earlier one. `None` for an empty slice or mixed kinds.
pub fn most_representative(descriptors: &[DescriptorRef<'_>]) -> Option<usize> {
    let n = descriptors.len();
    if n == 0 {
        return None;
    }
    let mut distances = vec![0f32; n * n];
    for i in 0..n {
        for j in i + 1..n {
            let d = descriptors[i].distance(&descriptors[j])?;
            distances[i * n + j] = d;
            distances[j * n + i] = d;
        }
    }
    let mut best: Option<(usize, f32)> = None;
    let mut row = Vec::with_capacity(n);
    for i in 0..n {
        row.clear();
        row.extend_from_slice(&distances[i * n..(i + 1) * n]);
        row.sort_by(f32::total_cmp);
        // ORB-SLAM3 takes element 0.5·(N−1) of the sorted row (itself included).
        let median = row[(n - 1) / 2];
        if best.is_none_or(|(_, m)| median < m) {
            best = Some((i, median));
        }
    }
    best.map(|(i, _)| i)
}
