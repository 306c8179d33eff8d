//! Binary descriptors from float ones: the sign of each of SuperPoint's 256
//! dimensions, packed into 32 bytes in ORB's layout, so that an unmodified
//! ORB-SLAM3 (Hamming matcher, DBoW2's `FORB`) can use them.
//!
//! Layout, as ORB-SLAM3's `computeOrbDescriptor` writes its comparisons:
//! bit `j` (least significant first) of byte `i` is dimension `8·i + j`,
//! set when that dimension is positive. The Hamming distance of two packed
//! rows counts the dimensions whose signs differ.

/// Packs each of the `rows.len() / dim` rows of `dim` floats into
/// `dim.div_ceil(8)` bytes of sign bits (unused high bits of a last partial
/// byte stay 0), appending them to `out`.
pub fn pack_sign_bits(rows: &[f32], dim: usize, out: &mut Vec<u8>) {
    if dim == 0 {
        return;
    }
    out.reserve(rows.len() / dim * dim.div_ceil(8));
    for row in rows.chunks_exact(dim) {
        for chunk in row.chunks(8) {
            let byte = chunk
                .iter()
                .enumerate()
                .fold(0u8, |b, (j, &v)| b | (u8::from(v > 0.0) << j));
            out.push(byte);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::features::descriptor_set::{BinaryDescriptor, DescriptorDistance};
    use proptest::prelude::*;

    #[test]
    fn bit_j_of_byte_i_is_the_sign_of_dimension_8i_plus_j() {
        let mut row = vec![-1.0f32; 256];
        row[0] = 0.5; // byte 0, bit 0
        row[9] = 0.1; // byte 1, bit 1
        row[255] = 0.2; // byte 31, bit 7
        row[17] = 0.0; // zero is not positive
        let mut out = Vec::new();
        pack_sign_bits(&row, 256, &mut out);
        assert_eq!(out.len(), 32);
        assert_eq!(out[0], 0b0000_0001);
        assert_eq!(out[1], 0b0000_0010);
        assert_eq!(out[2], 0);
        assert_eq!(out[31], 0b1000_0000);
        assert!(out[3..31].iter().all(|&b| b == 0));
    }

    #[test]
    fn a_partial_last_byte_keeps_its_high_bits_clear() {
        let mut out = Vec::new();
        pack_sign_bits(&[1.0; 10], 10, &mut out);
        assert_eq!(out, vec![0xff, 0b0000_0011]);
    }

    proptest! {
        /// The Hamming distance of the packed rows equals a brute-force
        /// count of the dimensions whose signs differ.
        #[test]
        fn hamming_of_packed_rows_counts_sign_disagreements(
            a in proptest::collection::vec(-1.0f32..1.0, 256),
            b in proptest::collection::vec(-1.0f32..1.0, 256),
        ) {
            let mut packed = Vec::new();
            pack_sign_bits(&a, 256, &mut packed);
            pack_sign_bits(&b, 256, &mut packed);
            let mut pa: BinaryDescriptor = [0; 32];
            let mut pb: BinaryDescriptor = [0; 32];
            pa.copy_from_slice(&packed[..32]);
            pb.copy_from_slice(&packed[32..]);
            let brute = a.iter().zip(&b).filter(|(x, y)| (**x > 0.0) != (**y > 0.0)).count();
            prop_assert_eq!(pa.distance_to(&pb) as usize, brute);
        }
    }
}
