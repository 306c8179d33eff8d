//! The two ways descriptor rows are compared and averaged when clustering:
//! squared L2 with the arithmetic mean (float rows), and Hamming with DBoW2's
//! per-bit majority (binary rows).

use super::DescriptorRows;

/// A distance and a mean over rows of one element type: what k-means and the
/// vocabulary tree need to know about a descriptor kind.
pub trait ClusterMetric: Clone + Send + Sync {
    /// One value of a row (`f32` or `u8`).
    type Elem: Copy + Default + PartialEq + std::fmt::Debug + Send + Sync;

    /// Values per row.
    fn row_len(&self) -> usize;

    /// The distance between two rows of [`row_len`](Self::row_len) values;
    /// smaller is nearer. It is also k-means++'s seeding weight.
    fn distance(&self, a: &[Self::Elem], b: &[Self::Elem]) -> f32;

    /// Writes the centre of the rows `members` of `rows` into `out`
    /// (`members` is not empty).
    fn mean(&self, rows: &DescriptorRows<Self::Elem>, members: &[u32], out: &mut [Self::Elem]);
}

/// Float rows (SuperPoint's 256 floats): squared L2 distance and the
/// arithmetic mean, accumulated in `f64`. Squared L2 orders rows as L2 does
/// and makes k-means++ pick with the usual D² weights.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct L2Float {
    /// Floats per row.
    pub dim: usize,
}

impl ClusterMetric for L2Float {
    type Elem = f32;

    fn row_len(&self) -> usize {
        self.dim
    }

    fn distance(&self, a: &[f32], b: &[f32]) -> f32 {
        // Eight partial sums so that the compiler can vectorise the loop.
        let mut acc = [0.0f32; 8];
        let (a_chunks, b_chunks) = (a.chunks_exact(8), b.chunks_exact(8));
        let (a_rest, b_rest) = (a_chunks.remainder(), b_chunks.remainder());
        for (x, y) in a_chunks.zip(b_chunks) {
            for k in 0..8 {
                let d = x[k] - y[k];
                acc[k] += d * d;
            }
        }
        let tail: f32 = a_rest
            .iter()
            .zip(b_rest)
            .map(|(x, y)| (x - y) * (x - y))
            .sum();
        acc.iter().sum::<f32>() + tail
    }

    fn mean(&self, rows: &DescriptorRows<f32>, members: &[u32], out: &mut [f32]) {
        let mut sum = vec![0.0f64; self.dim];
        for &m in members {
            for (s, &v) in sum.iter_mut().zip(rows.row(m as usize)) {
                *s += f64::from(v);
            }
        }
        let n = members.len().max(1) as f64;
        for (o, s) in out.iter_mut().zip(&sum) {
            *o = (s / n) as f32;
        }
    }
}

/// Binary rows (ORB's 32 bytes, or SuperPoint's packed sign bits): Hamming
/// distance and DBoW2's `FORB::meanValue`: a bit of the centre is set when at
/// least `ceil(n / 2)` of the `n` members have it set, so a tie (an even `n`,
/// half of them set) sets the bit, as DBoW2 does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HammingBinary {
    /// Bytes per row (32 for ORB).
    pub bytes: usize,
}

impl ClusterMetric for HammingBinary {
    type Elem = u8;

    fn row_len(&self) -> usize {
        self.bytes
    }

    fn distance(&self, a: &[u8], b: &[u8]) -> f32 {
        let (a_words, b_words) = (a.chunks_exact(8), b.chunks_exact(8));
        let (a_rest, b_rest) = (a_words.remainder(), b_words.remainder());
        let mut bits = 0u32;
        for (x, y) in a_words.zip(b_words) {
            let mut wx = [0u8; 8];
            let mut wy = [0u8; 8];
            wx.copy_from_slice(x);
            wy.copy_from_slice(y);
            bits += (u64::from_le_bytes(wx) ^ u64::from_le_bytes(wy)).count_ones();
        }
        for (x, y) in a_rest.iter().zip(b_rest) {
            bits += (x ^ y).count_ones();
        }
        bits as f32
    }

    fn mean(&self, rows: &DescriptorRows<u8>, members: &[u32], out: &mut [u8]) {
        let mut counts = vec![0u32; self.bytes * 8];
        for &m in members {
            for (byte, &v) in rows.row(m as usize).iter().enumerate() {
                for bit in 0..8 {
                    counts[byte * 8 + bit] += u32::from((v >> bit) & 1);
                }
            }
        }
        // DBoW2: N2 = n / 2 + n % 2; the bit is set when sum >= N2.
        let half = members.len().div_ceil(2) as u32;
        for (byte, o) in out.iter_mut().enumerate() {
            *o = (0..8).fold(0u8, |acc, bit| {
                acc | (u8::from(counts[byte * 8 + bit] >= half) << bit)
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn l2_is_squared_and_the_mean_is_arithmetic() {
        let m = L2Float { dim: 10 };
        let a: Vec<f32> = (0..10).map(|i| i as f32).collect();
        let b = vec![0.0f32; 10];
        assert_eq!(
            m.distance(&a, &b),
            (0..10).map(|i| (i * i) as f32).sum::<f32>()
        );
        let rows = DescriptorRows::from_flat(10, [a.clone(), b].concat()).unwrap();
        let mut out = vec![0.0; 10];
        m.mean(&rows, &[0, 1], &mut out);
        assert_eq!(out, a.iter().map(|v| v / 2.0).collect::<Vec<_>>());
    }

    #[test]
    fn hamming_counts_bits_and_ties_set_the_bit() {
        let m = HammingBinary { bytes: 9 };
        let a = [0u8; 9];
        let mut b = [0u8; 9];
        b[0] = 0b1011;
        b[8] = 0xff;
        assert_eq!(m.distance(&a, &b), 11.0);
        // Two members, the bit set in one: DBoW2 sets it (sum 1 >= N2 = 1).
        let rows = DescriptorRows::from_flat(9, [a, b].concat()).unwrap();
        let mut out = [0u8; 9];
        m.mean(&rows, &[0, 1], &mut out);
        assert_eq!(out, b);
        m.mean(&rows, &[0], &mut out);
        assert_eq!(out, a);
    }

    /// DBoW2's `FORB::meanValue`, transcribed: bits counted MSB first per
    /// byte, `N2 = n / 2 + n % 2`, bit set when `sum >= N2`.
    fn forb_mean_value(rows: &[Vec<u8>]) -> Vec<u8> {
        let bytes = rows[0].len();
        if rows.len() == 1 {
            return rows[0].clone();
        }
        let mut sum = vec![0usize; bytes * 8];
        for d in rows {
            for (j, &p) in d.iter().enumerate() {
                for b in 0..8 {
                    if p & (1 << (7 - b)) != 0 {
                        sum[j * 8 + b] += 1;
                    }
                }
            }
        }
        let n2 = rows.len() / 2 + rows.len() % 2;
        let mut mean = vec![0u8; bytes];
        for (i, &s) in sum.iter().enumerate() {
            if s >= n2 {
                mean[i / 8] |= 1 << (7 - (i % 8));
            }
        }
        mean
    }

    proptest! {
        /// The majority-bit mean equals DBoW2's `FORB::meanValue` and a
        /// bit-by-bit count, for any number of members.
        #[test]
        fn majority_mean_matches_dbow2_and_a_brute_force_count(
            rows in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 4), 1..12)
        ) {
            let m = HammingBinary { bytes: 4 };
            let flat = DescriptorRows::from_flat(4, rows.concat()).unwrap();
            let members: Vec<u32> = (0..rows.len() as u32).collect();
            let mut out = vec![0u8; 4];
            m.mean(&flat, &members, &mut out);
            prop_assert_eq!(&out, &forb_mean_value(&rows));
            for bit in 0..32 {
                let set = rows.iter().filter(|r| r[bit / 8] >> (bit % 8) & 1 == 1).count();
                prop_assert_eq!(out[bit / 8] >> (bit % 8) & 1 == 1, 2 * set >= rows.len());
            }
        }

        /// Hamming distance equals a bit-by-bit count.
        #[test]
        fn hamming_matches_a_bit_count(
            a in proptest::collection::vec(any::<u8>(), 32),
            b in proptest::collection::vec(any::<u8>(), 32),
        ) {
            let brute = (0..256).filter(|&i| (a[i / 8] ^ b[i / 8]) >> (i % 8) & 1 == 1).count();
            prop_assert_eq!(HammingBinary { bytes: 32 }.distance(&a, &b) as usize, brute);
        }
    }
}
