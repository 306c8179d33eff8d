//! The map file format, version 3 (version 1 had no sensor in the rig;
//! version 2 no descriptor-distance thresholds per keyframe).
//!
//! ```text
//! offset  size  field
//! 0       8     magic "SPSLMAP\x1a"
//! 8       4     format version, u32 little-endian (3)
//! 12      8     payload length in bytes, u64 little-endian
//! 20      4     CRC-32 (IEEE) of the payload, u32 little-endian
//! 24      …     payload: a `StoredAtlas`, postcard-encoded
//! ```
//!
//! The payload holds the file's metadata ([`MapFileMeta`]: spslam version,
//! extractor, model and codebook hashes, the rig, the descriptor
//! precision, the active map) and every atlas map ([`StoredMap`]): the
//! map's parts ([`MapParts`], serde) and its descriptor blocks, one per
//! keyframe, in the precision chosen at save time. A point's descriptor is
//! stored as a reference to the observed keyframe row it equals (ORB-SLAM3
//! picks one of them), or, when none does, in one block of the points'
//! own rows.
//! The place-recognition database is not stored: it is rebuilt from the
//! keyframes' descriptors with the codebook the hash names.
//!
//! Decoding checks, in order: length, magic, version, announced length,
//! checksum, postcard decoding (no trailing bytes), descriptor blocks, and
//! each map's invariants; the first failure is a [`StorageError`] naming
//! the file and the fault, and nothing is returned half-loaded.

use std::collections::HashMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::camera::{CameraRig, Sensor};
use crate::features::DescriptorSet;
use crate::map::{KeyFrameId, Map, MapParts, PointDescriptor};
use crate::optim::reprojection::PinholeStereo;

use super::checksum::crc32;
use super::descriptors::{
    decode_points, decode_set, encode_points, encode_set, DescriptorPrecision, StoredDescriptors,
};
use super::error::StorageError;

/// The first 8 bytes of every map file.
pub const MAGIC: [u8; 8] = *b"SPSLMAP\x1a";
/// The format version this build writes and reads.
pub const FORMAT_VERSION: u32 = 3;
/// Header bytes before the payload.
pub const HEADER_LEN: usize = 24;

/// The rig, as stored.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StoredRig {
    /// Focal length x (px).
    pub fx: f64,
    /// Focal length y (px).
    pub fy: f64,
    /// Principal point x (px).
    pub cx: f64,
    /// Principal point y (px).
    pub cy: f64,
    /// `fx · baseline`.
    pub bf: f64,
    /// Baseline (m).
    pub baseline: f64,
    /// Image width (px).
    pub width: usize,
    /// Image height (px).
    pub height: usize,
    /// Close-point depth threshold (m).
    pub close_depth: f64,
    /// Far depth limit (m).
    pub max_depth: Option<f64>,
    /// Frame rate.
    pub fps: f64,
    /// The sensor the map was made with (a monocular map has no metric scale).
    pub sensor: Sensor,
}

impl From<&CameraRig> for StoredRig {
    fn from(rig: &CameraRig) -> Self {
        Self {
            fx: rig.camera.fx,
            fy: rig.camera.fy,
            cx: rig.camera.cx,
            cy: rig.camera.cy,
            bf: rig.camera.bf,
            baseline: rig.baseline,
            width: rig.width,
            height: rig.height,
            close_depth: rig.close_depth,
            max_depth: rig.max_depth,
            fps: rig.fps,
            sensor: rig.sensor,
        }
    }
}

impl From<&StoredRig> for CameraRig {
    fn from(r: &StoredRig) -> Self {
        CameraRig {
            sensor: r.sensor,
            camera: PinholeStereo {
                fx: r.fx,
                fy: r.fy,
                cx: r.cx,
                cy: r.cy,
                bf: r.bf,
            },
            baseline: r.baseline,
            width: r.width,
            height: r.height,
            close_depth: r.close_depth,
            // Not stored: a loaded map follows the default policy.
            far_points_stereo: false,
            max_depth: r.max_depth,
            fps: r.fps,
        }
    }
}

/// What a map file says about how it was made.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MapFileMeta {
    /// The spslam version that wrote it.
    pub spslam_version: String,
    /// The extractor's name (e.g. `superpoint-int8`).
    pub extractor: String,
    /// The extractor settings, as text (for `spslam map info`).
    pub extractor_settings: String,
    /// Hash of the model file the descriptors came from (hex), if any.
    pub model_hash: Option<String>,
    /// Hash of the place-recognition codebook's settings (hex), if any.
    pub codebook_hash: Option<String>,
    /// The camera rig.
    pub rig: StoredRig,
    /// How float descriptors are stored.
    pub precision: DescriptorPrecision,
    /// The atlas map that was active.
    pub active_map: usize,
}

/// One atlas map as stored.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StoredMap {
    /// Its index in the atlas.
    pub index: usize,
    /// The first input frame processed in it.
    pub first_frame: usize,
    /// The map it was merged into, if any.
    pub merged_into: Option<usize>,
    /// Keyframes, points and graph (descriptors skipped).
    pub parts: MapParts,
    /// One block per keyframe, in `parts.keyframes` order.
    pub keyframe_descriptors: Vec<StoredDescriptors>,
    /// Per point, in `parts.points` order: `Some(j)` when its descriptor
    /// is the row of its `j`-th observation (the usual case: ORB-SLAM3's
    /// representative descriptor is one of the observed rows), `None`
    /// when it has its own row in `point_descriptors`.
    pub point_descriptor_sources: Vec<Option<u32>>,
    /// The points' own rows, in order.
    pub point_descriptors: StoredDescriptors,
}

/// The whole payload.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StoredAtlas {
    /// Metadata.
    pub meta: MapFileMeta,
    /// Every atlas map, by index.
    pub maps: Vec<StoredMap>,
}

/// An atlas map to save.
#[derive(Debug, Clone, Copy)]
pub struct MapToSave<'a> {
    /// Its index in the atlas.
    pub index: usize,
    /// The first input frame processed in it.
    pub first_frame: usize,
    /// The map it was merged into, if any.
    pub merged_into: Option<usize>,
    /// The map.
    pub map: &'a Map,
}

/// An atlas map loaded, checked.
#[derive(Debug)]
pub struct LoadedMap {
    /// Its index in the atlas.
    pub index: usize,
    /// The first input frame processed in it.
    pub first_frame: usize,
    /// The map it was merged into, if any.
    pub merged_into: Option<usize>,
    /// The map (it passed [`Map::check_invariants`]).
    pub map: Map,
}

/// A map file loaded, checked.
#[derive(Debug)]
pub struct LoadedAtlas {
    /// Its metadata.
    pub meta: MapFileMeta,
    /// Its maps, by index.
    pub maps: Vec<LoadedMap>,
}

/// The file's bytes for `maps` (descriptors in `meta.precision`).
pub fn encode(meta: &MapFileMeta, maps: &[MapToSave<'_>]) -> Result<Vec<u8>, String> {
    let stored: Vec<StoredMap> = maps
        .iter()
        .map(|m| {
            let parts = m.map.to_parts();
            let keyframe_descriptors = parts
                .keyframes
                .iter()
                .map(|k| encode_set(&k.descriptors, meta.precision))
                .collect();
            let point_descriptor_sources = point_sources(&parts);
            let own: Vec<_> = parts
                .points
                .iter()
                .zip(&point_descriptor_sources)
                .filter(|(_, source)| source.is_none())
                .map(|(p, _)| &p.descriptor)
                .collect();
            let point_descriptors = encode_points(&own, meta.precision);
            StoredMap {
                index: m.index,
                first_frame: m.first_frame,
                merged_into: m.merged_into,
                parts,
                keyframe_descriptors,
                point_descriptor_sources,
                point_descriptors,
            }
        })
        .collect();
    let atlas = StoredAtlas {
        meta: meta.clone(),
        maps: stored,
    };
    let payload = postcard::to_stdvec(&atlas).map_err(|e| e.to_string())?;
    let mut bytes = Vec::with_capacity(HEADER_LEN + payload.len());
    bytes.extend_from_slice(&MAGIC);
    bytes.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    bytes.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    bytes.extend_from_slice(&crc32(&payload).to_le_bytes());
    bytes.extend_from_slice(&payload);
    Ok(bytes)
}

/// Per point: the observation whose keyframe row equals its descriptor.
fn point_sources(parts: &MapParts) -> Vec<Option<u32>> {
    let keyframes: HashMap<KeyFrameId, &DescriptorSet> = parts
        .keyframes
        .iter()
        .map(|k| (k.id, &k.descriptors))
        .collect();
    parts
        .points
        .iter()
        .map(|p| {
            p.observations.iter().position(|(kf, index)| {
                keyframes
                    .get(kf)
                    .and_then(|set| PointDescriptor::from_set(set, *index))
                    .is_some_and(|row| row == p.descriptor)
            })
        })
        .map(|j| j.map(|j| j as u32))
        .collect()
}

/// Puts the points' descriptors back: from the observed rows or their own.
fn restore_point_descriptors(
    parts: &mut MapParts,
    sources: &[Option<u32>],
    own: Vec<PointDescriptor>,
) -> Result<(), String> {
    if sources.len() != parts.points.len() {
        return Err(format!(
            "{} descriptor sources for {} points",
            sources.len(),
            parts.points.len()
        ));
    }
    let keyframes: HashMap<KeyFrameId, &DescriptorSet> = parts
        .keyframes
        .iter()
        .map(|k| (k.id, &k.descriptors))
        .collect();
    let mut own = own.into_iter();
    let mut restored = Vec::with_capacity(parts.points.len());
    for (p, source) in parts.points.iter().zip(sources) {
        let descriptor = match source {
            None => own
                .next()
                .ok_or_else(|| format!("{} has no stored descriptor", p.id))?,
            Some(j) => {
                let (kf, index) = p.observations.get(*j as usize).ok_or_else(|| {
                    format!(
                        "{} takes its descriptor from observation {j}, which it does not have",
                        p.id
                    )
                })?;
                keyframes
                    .get(kf)
                    .and_then(|set| PointDescriptor::from_set(set, *index))
                    .ok_or_else(|| {
                        format!(
                            "{} takes its descriptor from {kf} keypoint {index}, which has none",
                            p.id
                        )
                    })?
            }
        };
        restored.push(descriptor);
    }
    if own.next().is_some() {
        return Err("more point descriptors stored than points use".into());
    }
    for (p, d) in parts.points.iter_mut().zip(restored) {
        p.descriptor = d;
    }
    Ok(())
}

/// The header's checks: magic, version, length, checksum; the payload.
fn checked_payload<'b>(path: &Path, bytes: &'b [u8]) -> Result<&'b [u8], StorageError> {
    let path_buf = || path.to_path_buf();
    if bytes.len() < 8 || bytes[..8] != MAGIC {
        return Err(StorageError::NotAMapFile { path: path_buf() });
    }
    if bytes.len() < HEADER_LEN {
        return Err(StorageError::Truncated {
            path: path_buf(),
            expected: HEADER_LEN as u64,
            actual: bytes.len() as u64,
        });
    }
    let word = |at: usize| [bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]];
    let version = u32::from_le_bytes(word(8));
    if version != FORMAT_VERSION {
        return Err(StorageError::UnsupportedVersion {
            path: path_buf(),
            found: version,
            supported: FORMAT_VERSION,
        });
    }
    let mut length = [0u8; 8];
    length.copy_from_slice(&bytes[12..20]);
    let expected = u64::from_le_bytes(length);
    let payload = &bytes[HEADER_LEN..];
    if expected != payload.len() as u64 {
        return Err(StorageError::Truncated {
            path: path_buf(),
            expected,
            actual: payload.len() as u64,
        });
    }
    let stored = u32::from_le_bytes(word(20));
    let computed = crc32(payload);
    if stored != computed {
        return Err(StorageError::ChecksumMismatch {
            path: path_buf(),
            stored,
            computed,
        });
    }
    Ok(payload)
}

/// Decodes a map file's bytes (`path` names it in errors).
pub fn decode(path: &Path, bytes: &[u8]) -> Result<LoadedAtlas, StorageError> {
    let payload = checked_payload(path, bytes)?;
    let corrupt = |reason: String| StorageError::Corrupt {
        path: path.to_path_buf(),
        reason,
    };
    let (atlas, rest): (StoredAtlas, &[u8]) =
        postcard::take_from_bytes(payload).map_err(|e| corrupt(format!("postcard: {e}")))?;
    if !rest.is_empty() {
        return Err(corrupt(format!("{} bytes after the atlas", rest.len())));
    }
    check_atlas_shape(&atlas).map_err(corrupt)?;
    let mut maps = Vec::with_capacity(atlas.maps.len());
    for stored in atlas.maps {
        let StoredMap {
            index,
            first_frame,
            merged_into,
            mut parts,
            keyframe_descriptors,
            point_descriptor_sources,
            point_descriptors,
        } = stored;
        if keyframe_descriptors.len() != parts.keyframes.len() {
            return Err(corrupt(format!(
                "map {index}: {} descriptor blocks for {} keyframes",
                keyframe_descriptors.len(),
                parts.keyframes.len()
            )));
        }
        for (kf, block) in parts.keyframes.iter_mut().zip(&keyframe_descriptors) {
            kf.descriptors =
                decode_set(block).map_err(|e| corrupt(format!("map {index}, {}: {e}", kf.id)))?;
        }
        let own_rows = point_descriptor_sources
            .iter()
            .filter(|s| s.is_none())
            .count();
        let own = decode_points(&point_descriptors, own_rows)
            .map_err(|e| corrupt(format!("map {index}: {e}")))?;
        restore_point_descriptors(&mut parts, &point_descriptor_sources, own)
            .map_err(|e| corrupt(format!("map {index}: {e}")))?;
        let map = Map::from_parts(parts).map_err(|violation| StorageError::Inconsistent {
            path: path.to_path_buf(),
            map: index,
            violation,
        })?;
        maps.push(LoadedMap {
            index,
            first_frame,
            merged_into,
            map,
        });
    }
    Ok(LoadedAtlas {
        meta: atlas.meta,
        maps,
    })
}

/// The atlas-level checks: maps numbered 0.., merges into existing maps,
/// the active map present and not merged.
fn check_atlas_shape(atlas: &StoredAtlas) -> Result<(), String> {
    let n = atlas.maps.len();
    if n == 0 {
        return Err("the atlas holds no map".into());
    }
    for (i, m) in atlas.maps.iter().enumerate() {
        if m.index != i {
            return Err(format!("map {i} is stored with index {}", m.index));
        }
        if let Some(into) = m.merged_into {
            if into >= n || into == i {
                return Err(format!(
                    "map {i} is merged into map {into}, which is not another map of the atlas"
                ));
            }
        }
    }
    let active = atlas.meta.active_map;
    match atlas.maps.get(active) {
        None => Err(format!(
            "the active map {active} is not in the atlas ({n} maps)"
        )),
        Some(m) if m.merged_into.is_some() => {
            Err(format!("the active map {active} is marked merged"))
        }
        Some(_) => Ok(()),
    }
}

/// The metadata of a map file without decoding its maps' descriptors or
/// checking its maps (for `spslam map info`), with the payload's size.
pub fn peek(path: &Path, bytes: &[u8]) -> Result<StoredAtlas, StorageError> {
    let payload = checked_payload(path, bytes)?;
    postcard::from_bytes(payload).map_err(|e| StorageError::Corrupt {
        path: path.to_path_buf(),
        reason: format!("postcard: {e}"),
    })
}
