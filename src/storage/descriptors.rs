//! Descriptor blocks as stored: float rows in `f32`, `f16` or `u8`
//! (quantised), chosen at save time; ORB's binary rows as they are.
//!
//! - `f32`: bit-exact;
//! - `f16`: round to nearest (binary16), relative error ≤ 2⁻¹¹;
//! - `u8`: each row scaled by its largest magnitude to −127…127, one `f32`
//!   scale per row; error ≤ scale / 254 per value.
//!
//! Payloads are little-endian byte strings (`serde_bytes`: one copy on
//! load, no per-value decoding through serde).

use serde::{Deserialize, Serialize};

use crate::features::descriptor_set::BinaryDescriptor;
use crate::features::DescriptorSet;
use crate::map::PointDescriptor;

use super::half::{f16_bits_to_f32, f32_to_f16_bits};

/// How float descriptors are stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum DescriptorPrecision {
    /// 4 bytes per value, exact.
    F32,
    /// 2 bytes per value (half precision).
    #[default]
    F16,
    /// 1 byte per value plus a scale per row.
    U8,
}

impl DescriptorPrecision {
    /// Its name in files and reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::F32 => "f32",
            Self::F16 => "f16",
            Self::U8 => "u8",
        }
    }
}

impl std::str::FromStr for DescriptorPrecision {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "f32" => Ok(Self::F32),
            "f16" => Ok(Self::F16),
            "u8" => Ok(Self::U8),
            other => Err(format!(
                "unknown descriptor precision {other:?}: use f32, f16 or u8"
            )),
        }
    }
}

/// One stored block of descriptor rows.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum StoredDescriptors {
    /// Float rows of `dim` values as `f32`.
    F32 {
        /// Values per row.
        dim: u32,
        /// Little-endian `f32`s.
        #[serde(with = "serde_bytes")]
        bytes: Vec<u8>,
    },
    /// Float rows as binary16.
    F16 {
        /// Values per row.
        dim: u32,
        /// Little-endian binary16 values.
        #[serde(with = "serde_bytes")]
        bytes: Vec<u8>,
    },
    /// Float rows quantised to `i8` with one scale per row.
    U8 {
        /// Values per row.
        dim: u32,
        /// Little-endian `f32` scale per row.
        #[serde(with = "serde_bytes")]
        scales: Vec<u8>,
        /// One `i8` per value.
        #[serde(with = "serde_bytes")]
        bytes: Vec<u8>,
    },
    /// ORB rows, 32 bytes each.
    Binary {
        /// The rows' bytes.
        #[serde(with = "serde_bytes")]
        bytes: Vec<u8>,
    },
}

/// Why a stored block cannot be decoded.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct BlockError(pub String);

fn encode_floats(dim: usize, data: &[f32], precision: DescriptorPrecision) -> StoredDescriptors {
    let dim_u32 = dim as u32;
    match precision {
        DescriptorPrecision::F32 => StoredDescriptors::F32 {
            dim: dim_u32,
            bytes: data.iter().flat_map(|v| v.to_le_bytes()).collect(),
        },
        DescriptorPrecision::F16 => StoredDescriptors::F16 {
            dim: dim_u32,
            bytes: data
                .iter()
                .flat_map(|v| f32_to_f16_bits(*v).to_le_bytes())
                .collect(),
        },
        DescriptorPrecision::U8 => {
            let (mut scales, mut bytes) = (Vec::new(), Vec::with_capacity(data.len()));
            for row in data.chunks(dim.max(1)) {
                let largest = row.iter().fold(0.0f32, |m, v| m.max(v.abs()));
                let scale = if largest > 0.0 && largest.is_finite() {
                    largest / 127.0
                } else {
                    1.0
                };
                scales.extend(scale.to_le_bytes());
                bytes.extend(
                    row.iter()
                        .map(|v| ((v / scale).round().clamp(-127.0, 127.0) as i8) as u8),
                );
            }
            StoredDescriptors::U8 {
                dim: dim_u32,
                scales,
                bytes,
            }
        }
    }
}

fn decode_floats(stored: &StoredDescriptors) -> Result<(usize, Vec<f32>), BlockError> {
    let not_whole = |what: &str| {
        Err(BlockError(format!(
            "{what} block whose length is not whole rows"
        )))
    };
    match stored {
        StoredDescriptors::F32 { dim, bytes } => {
            let d = *dim as usize;
            if !bytes.len().is_multiple_of(4) || !(bytes.len() / 4).is_multiple_of(d) {
                return not_whole("an f32");
            }
            let data = bytes
                .chunks_exact(4)
                .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                .collect();
            Ok((d, data))
        }
        StoredDescriptors::F16 { dim, bytes } => {
            let d = *dim as usize;
            if !bytes.len().is_multiple_of(2) || !(bytes.len() / 2).is_multiple_of(d) {
                return not_whole("an f16");
            }
            let data = bytes
                .chunks_exact(2)
                .map(|b| f16_bits_to_f32(u16::from_le_bytes([b[0], b[1]])))
                .collect();
            Ok((d, data))
        }
        StoredDescriptors::U8 { dim, scales, bytes } => {
            let d = *dim as usize;
            let rows = bytes.len().checked_div(d).unwrap_or(0);
            if !bytes.len().is_multiple_of(d) || scales.len() != rows * 4 {
                return Err(BlockError(
                    "a u8 block whose rows and scales disagree".into(),
                ));
            }
            let mut data = Vec::with_capacity(bytes.len());
            for (row, scale) in bytes.chunks(d.max(1)).zip(scales.chunks_exact(4)) {
                let scale = f32::from_le_bytes([scale[0], scale[1], scale[2], scale[3]]);
                data.extend(row.iter().map(|b| f32::from(*b as i8) * scale));
            }
            Ok((d, data))
        }
        StoredDescriptors::Binary { .. } => {
            Err(BlockError("a binary block where float rows belong".into()))
        }
    }
}

/// Stores a keyframe's descriptor block.
pub fn encode_set(set: &DescriptorSet, precision: DescriptorPrecision) -> StoredDescriptors {
    match set {
        DescriptorSet::Float { dim, data } => encode_floats(*dim, data, precision),
        DescriptorSet::Binary { data } => StoredDescriptors::Binary {
            bytes: data.iter().flat_map(|d| d.iter().copied()).collect(),
        },
    }
}

/// A keyframe's descriptor block back.
pub fn decode_set(stored: &StoredDescriptors) -> Result<DescriptorSet, BlockError> {
    if let StoredDescriptors::Binary { bytes } = stored {
        return binary_rows(bytes).map(|data| DescriptorSet::Binary { data });
    }
    let (dim, data) = decode_floats(stored)?;
    Ok(DescriptorSet::Float { dim, data })
}

fn binary_rows(bytes: &[u8]) -> Result<Vec<BinaryDescriptor>, BlockError> {
    if !bytes.len().is_multiple_of(32) {
        return Err(BlockError(
            "a binary block whose length is not whole 32-byte rows".into(),
        ));
    }
    Ok(bytes
        .chunks_exact(32)
        .map(|c| {
            let mut row = [0u8; 32];
            row.copy_from_slice(c);
            row
        })
        .collect())
}

/// Stores every point's descriptor in one block (rows in point order).
pub fn encode_points(
    descriptors: &[&PointDescriptor],
    precision: DescriptorPrecision,
) -> StoredDescriptors {
    match descriptors.first() {
        Some(PointDescriptor::Binary(_)) => StoredDescriptors::Binary {
            bytes: descriptors
                .iter()
                .flat_map(|d| match d {
                    PointDescriptor::Binary(b) => b.to_vec(),
                    PointDescriptor::Float(_) => vec![0; 32],
                })
                .collect(),
        },
        _ => {
            let dim = descriptors.iter().map(|d| float_len(d)).max().unwrap_or(0);
            let mut data = Vec::with_capacity(dim * descriptors.len());
            for d in descriptors {
                match d {
                    PointDescriptor::Float(v) if v.len() == dim => data.extend_from_slice(v),
                    _ => data.extend(std::iter::repeat_n(0.0, dim)),
                }
            }
            encode_floats(dim, &data, precision)
        }
    }
}

fn float_len(d: &PointDescriptor) -> usize {
    match d {
        PointDescriptor::Float(v) => v.len(),
        PointDescriptor::Binary(_) => 0,
    }
}

/// The points' descriptors back, `count` of them.
pub fn decode_points(
    stored: &StoredDescriptors,
    count: usize,
) -> Result<Vec<PointDescriptor>, BlockError> {
    let out: Vec<PointDescriptor> = match stored {
        StoredDescriptors::Binary { bytes } => binary_rows(bytes)?
            .into_iter()
            .map(PointDescriptor::Binary)
            .collect(),
        _ => {
            let (dim, data) = decode_floats(stored)?;
            if dim == 0 {
                vec![
                    PointDescriptor::Float(Vec::new().into());
                    if data.is_empty() { count } else { 0 }
                ]
            } else {
                data.chunks_exact(dim)
                    .map(|row| PointDescriptor::Float(row.into()))
                    .collect()
            }
        }
    };
    if out.len() != count {
        return Err(BlockError(format!(
            "{} point descriptors stored for {count} points",
            out.len()
        )));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rows() -> DescriptorSet {
        let dim = 8;
        let data = (0..5 * dim)
            .map(|i| ((i as f32) * 0.37).sin() * 0.5)
            .collect();
        DescriptorSet::Float { dim, data }
    }

    #[test]
    fn f32_is_bit_exact_and_the_others_are_close() {
        let set = rows();
        let DescriptorSet::Float { data, .. } = &set else {
            unreachable!("float rows")
        };
        for (precision, tolerance) in [
            (DescriptorPrecision::F32, 0.0f32),
            (DescriptorPrecision::F16, 0.5 / 1024.0),
            (DescriptorPrecision::U8, 0.5 / 254.0 + 1e-6),
        ] {
            let back = decode_set(&encode_set(&set, precision));
            let Ok(DescriptorSet::Float { dim, data: got }) = back else {
                panic!("{precision:?}: {back:?}")
            };
            assert_eq!(dim, 8);
            let worst = got
                .iter()
                .zip(data)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f32::max);
            assert!(worst <= tolerance, "{precision:?}: {worst}");
            if precision == DescriptorPrecision::F32 {
                assert_eq!(&got, data);
            }
        }
    }

    #[test]
    fn blocks_of_the_wrong_length_are_errors() {
        let bad = [
            StoredDescriptors::F32 {
                dim: 3,
                bytes: vec![0; 8],
            },
            StoredDescriptors::F16 {
                dim: 3,
                bytes: vec![0; 5],
            },
            StoredDescriptors::U8 {
                dim: 4,
                scales: vec![0; 4],
                bytes: vec![0; 9],
            },
            StoredDescriptors::Binary { bytes: vec![0; 31] },
            StoredDescriptors::F32 {
                dim: 0,
                bytes: vec![0; 4],
            },
        ];
        for b in &bad {
            assert!(decode_set(b).is_err(), "{b:?}");
        }
        let points = StoredDescriptors::F32 {
            dim: 2,
            bytes: vec![0; 16],
        };
        assert!(decode_points(&points, 2).is_ok());
        assert!(decode_points(&points, 3).is_err());
    }
}
