//! Assembling a [`SlamSystem`] from ORB-SLAM3 settings: the extractors
//! for the sensor, the front end, loop closing with the model's codebook,
//! and what a saved map records about them. `spslam run` and the Python
//! package's `System` both build their system here.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::camera::{CameraRig, Sensor};
use crate::error::SlamError;
use crate::features::{
    threads_per_extractor, FeatureExtractor, OrbConfig, OrbExtractor, SuperPointExtractor,
};
use crate::loop_closing::LoopThresholds;
use crate::place::{default_codebook_for, Codebook};
use crate::settings::SlamSettings;
use crate::storage::crc32;
use crate::tracking::Frontend;

use super::{MapProvenance, SecondLook, SlamSystem};

/// Which features the system tracks.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ExtractorKind {
    /// SuperPoint + ANMS with the settings' `SuperPoint.*` keys.
    #[default]
    SuperPoint,
    /// ORB-SLAM3's ORB extractor with the settings' `ORBextractor.*` keys.
    Orb,
}

/// The choices a caller makes beyond the settings file.
#[derive(Clone, Debug, PartialEq)]
pub struct SystemOptions {
    /// The features.
    pub extractor: ExtractorKind,
    /// Pyramid levels; `None` takes the settings' (`SuperPoint.nLevels`
    /// or `ORBextractor.nLevels`).
    pub levels: Option<usize>,
    /// Loop closing and map merging (SuperPoint only: ORB has no codebook).
    pub loop_closing: bool,
    /// The VLAD codebook; `None` is the one shipped for the model
    /// ([`default_codebook_for`]).
    pub codebook: Option<PathBuf>,
    /// Run every stage of each loop and merge candidate's check and
    /// record the counts ([`LoopThresholds::record_every_stage`]).
    pub record_loop_stages: bool,
}

impl Default for SystemOptions {
    /// SuperPoint with the settings' levels, loop closing with the shipped codebook.
    fn default() -> Self {
        Self {
            extractor: ExtractorKind::SuperPoint,
            levels: None,
            loop_closing: true,
            codebook: None,
            record_loop_stages: false,
        }
    }
}

/// A system ready to track, and what was chosen for it.
pub struct AssembledSystem {
    /// The system (local mapping inline until
    /// [`SlamSystem::spawn_mapping_thread`] is called).
    pub system: SlamSystem,
    /// How the network runs, for reports (`int8 on cpu, 1 level`).
    pub inference: String,
    /// The pyramid levels used.
    pub levels: usize,
    /// The extractor settings, model and codebook a saved map records.
    pub provenance: MapProvenance,
}

/// A file's identity for a map file's provenance: its CRC-32 and length.
pub fn file_fingerprint(path: &Path) -> Option<String> {
    let bytes = std::fs::read(path).ok()?;
    Some(format!("crc32:{:08x}/{}B", crc32(&bytes), bytes.len()))
}

/// The extractors of `kind`: the left one, and the right one for stereo.
#[allow(clippy::type_complexity)]
fn extractors(
    kind: ExtractorKind,
    settings: &SlamSettings,
    levels: usize,
    sensor: Sensor,
) -> Result<(Box<dyn FeatureExtractor>, Option<Box<dyn FeatureExtractor>>), SlamError> {
    let stereo = sensor == Sensor::Stereo;
    let e = &settings.extractor;
    let created = |source| SlamError::Extractor { source };
    match kind {
        ExtractorKind::Orb => {
            let config = OrbConfig {
                n_features: e.n_features,
                scale_factor: e.scale_factor as f32,
                n_levels: levels,
                ini_th_fast: e.ini_th_fast,
                min_th_fast: e.min_th_fast,
            };
            let right: Option<Box<dyn FeatureExtractor>> = if stereo {
                Some(Box::new(OrbExtractor::new(config).map_err(created)?))
            } else {
                None
            };
            Ok((Box::new(OrbExtractor::new(config).map_err(created)?), right))
        }
        ExtractorKind::SuperPoint => {
            // One ONNX Runtime thread pool per image; a stereo pair's two
            // run in parallel, a single image gets every core.
            let threads = threads_per_extractor(if stereo { 2 } else { 1 });
            let config = e.superpoint_config(levels, threads);
            let right: Option<Box<dyn FeatureExtractor>> = if stereo {
                Some(Box::new(
                    SuperPointExtractor::new(config.clone()).map_err(created)?,
                ))
            } else {
                None
            };
            Ok((
                Box::new(SuperPointExtractor::new(config).map_err(created)?),
                right,
            ))
        }
    }
}

/// Builds the system for `sensor` on images of `size` (width, height):
/// the rig from the settings, the extractors, the front end, and loop
/// closing when asked (SuperPoint only).
pub fn assemble_system(
    settings: &SlamSettings,
    sensor: Sensor,
    size: (usize, usize),
    options: &SystemOptions,
) -> Result<AssembledSystem, SlamError> {
    let rig = CameraRig::for_sensor(settings, sensor, size.0, size.1)?;
    let levels = options.levels.unwrap_or(match options.extractor {
        ExtractorKind::SuperPoint => settings
            .extractor
            .superpoint_levels_for(sensor == Sensor::Monocular),
        ExtractorKind::Orb => settings.extractor.n_levels,
    });
    let (left, right) = extractors(options.extractor, settings, levels, sensor)?;
    let inference = left.inference_summary();
    let frontend = match right {
        Some(right) => Frontend::new(left, right, &rig),
        None => Frontend::single(left, &rig)?,
    };
    let mut system = SlamSystem::new(rig, frontend);
    if let Some(deeper) = settings.extractor.second_look_levels_for(levels) {
        let (kind, settings) = (options.extractor, settings.clone());
        system.set_second_look(Some(SecondLook::new(
            deeper,
            Box::new(move || {
                let (left, right) = extractors(kind, &settings, deeper, sensor)?;
                match right {
                    Some(right) => Ok(Frontend::new(left, right, &rig)),
                    None => Frontend::single(left, &rig),
                }
            }),
        )));
    }
    let superpoint = options.extractor == ExtractorKind::SuperPoint;
    let model_hash = if superpoint {
        file_fingerprint(
            &settings
                .extractor
                .superpoint_config(levels, 1)
                .resolved_model_path(),
        )
    } else {
        None
    };
    let mut codebook_hash = None;
    if options.loop_closing && superpoint {
        let config = settings
            .extractor
            .superpoint_config(levels, threads_per_extractor(2));
        let path = options
            .codebook
            .clone()
            .unwrap_or_else(|| default_codebook_for(&config));
        let codebook =
            Codebook::load_for(&path, &config).map_err(|source| SlamError::Codebook {
                path: path.clone(),
                source,
            })?;
        let thresholds = LoopThresholds {
            record_every_stage: options.record_loop_stages,
            ..LoopThresholds::default()
        };
        system.enable_loop_closing(Arc::new(codebook.vlad), thresholds)?;
        codebook_hash = file_fingerprint(&path);
    }
    Ok(AssembledSystem {
        system,
        inference,
        levels,
        provenance: MapProvenance {
            extractor_settings: format!("{:?}", settings.extractor),
            model_hash,
            codebook_hash,
        },
    })
}
