//! A process-wide cache of extracted features, for tests that run SLAM
//! several times over the same images (with and without loop closing, a
//! saved map localised again): each image goes through the network once
//! per test binary, so the suite spends its time on what it tests.
//!
//! Extraction is deterministic on one machine (the same image and
//! configuration give the same keypoints and descriptors), so a cached
//! result is exactly what a second extraction would return. Keys are two
//! independent 64-bit hashes of the configuration's tag and the pixels.
//! Under `tools/run_tests.py` the cache goes on disk as well
//! ([`super::disk_cache`]): the test processes of one run share it.
//! Only for runs with local mapping inline: a cached frame costs no time,
//! which would change how far a mapping thread falls behind.

use std::collections::HashMap;
use std::hash::Hash;
use std::sync::{Arc, Mutex, OnceLock};

use spslam::features::pyramid::ScaleTables;
use spslam::features::{
    DescriptorKind, DescriptorSet, FeatureError, FeatureExtractor, FrameFeatures, GrayImageView,
    Keypoint, StageTimings,
};

use super::disk_cache::{self, Reader, Writer};

type Key = (u64, u64);

/// The cached features and how many extractions were answered and run.
#[derive(Default)]
struct Cache {
    features: HashMap<Key, Arc<FrameFeatures>>,
    hits: usize,
    misses: usize,
}

fn cache() -> &'static Mutex<Cache> {
    static CACHE: OnceLock<Mutex<Cache>> = OnceLock::new();
    CACHE.get_or_init(Mutex::default)
}

/// How many extractions the cache answered and how many ran, in this process.
pub fn hits_and_misses() -> (usize, usize) {
    cache().lock().map(|c| (c.hits, c.misses)).unwrap_or((0, 0))
}

/// A [`FeatureExtractor`] that answers from the process-wide cache and
/// extracts (and remembers) only images it has not seen with this tag.
pub struct CachedExtractor<E> {
    inner: E,
    tag: String,
}

impl<E: FeatureExtractor> CachedExtractor<E> {
    /// Wraps `inner`; `tag` must tell its configuration apart from every
    /// other configuration cached in this process (e.g. `format!("{config:?}")`).
    pub fn new(inner: E, tag: impl Into<String>) -> Self {
        Self {
            inner,
            tag: tag.into(),
        }
    }

    fn key(&self, image: &GrayImageView<'_>) -> Key {
        disk_cache::key(|h| {
            self.tag.hash(h);
            self.inner.name().hash(h);
            (image.width(), image.height()).hash(h);
            for y in 0..image.height() {
                image.row(y).hash(h);
            }
        })
    }
}

const DISK_KIND: &str = "features";

/// Keypoints and timings through their serde derives (postcard, as the
/// map files); the descriptor block, which has none, after them.
fn encode(features: &FrameFeatures) -> Vec<u8> {
    let head = postcard::to_stdvec(&(&features.keypoints, &features.timings)).unwrap_or_default();
    let mut w = Writer::default();
    w.bytes(&head);
    match &features.descriptors {
        DescriptorSet::Float { dim, data } => {
            w.u64(0);
            w.u64(*dim as u64);
            w.f32s(data);
        }
        DescriptorSet::Binary { data } => {
            w.u64(1);
            w.bytes(data.as_flattened());
        }
    }
    w.0
}

fn decode(bytes: &[u8]) -> Option<FrameFeatures> {
    let mut r = Reader(bytes);
    let (keypoints, timings): (Vec<Keypoint>, StageTimings) =
        postcard::from_bytes(&r.bytes()?).ok()?;
    let descriptors = match r.u64()? {
        0 => DescriptorSet::Float {
            dim: usize::try_from(r.u64()?).ok()?,
            data: r.f32s()?,
        },
        1 => {
            let bytes = r.bytes()?;
            let (rows, rest) = bytes.as_chunks();
            if !rest.is_empty() {
                return None;
            }
            DescriptorSet::Binary {
                data: rows.to_vec(),
            }
        }
        _ => return None,
    };
    r.is_done().then_some(FrameFeatures {
        keypoints,
        descriptors,
        timings,
    })
}

impl<E: FeatureExtractor> FeatureExtractor for CachedExtractor<E> {
    fn extract(&mut self, image: GrayImageView<'_>) -> Result<FrameFeatures, FeatureError> {
        let key = self.key(&image);
        // The lock is held for the lookup and the insert, never across extraction.
        let cached = cache().lock().ok().and_then(|mut c| {
            let found = c.features.get(&key).cloned();
            match found {
                Some(_) => c.hits += 1,
                None => c.misses += 1,
            }
            found
        });
        if let Some(features) = cached {
            return Ok(features.as_ref().clone());
        }
        let inner = &mut self.inner;
        let features =
            disk_cache::get_or_compute(DISK_KIND, key, decode, encode, || inner.extract(image))?;
        if let Ok(mut c) = cache().lock() {
            c.features.insert(key, Arc::new(features.clone()));
        }
        Ok(features)
    }

    fn scale_tables(&self) -> &ScaleTables {
        self.inner.scale_tables()
    }

    fn name(&self) -> &str {
        self.inner.name()
    }

    fn descriptor_kind(&self) -> DescriptorKind {
        self.inner.descriptor_kind()
    }

    fn descriptor_cell(&self) -> Option<f32> {
        self.inner.descriptor_cell()
    }

    fn inference_summary(&self) -> String {
        self.inner.inference_summary()
    }
}
