//! Saving the atlas to a map file (`crate::storage`): a snapshot of every
//! map under its read lock, with what the caller knows of the extractor,
//! model and codebook.

use std::path::Path;

use crate::camera::CameraRig;
use crate::error::SlamError;
use crate::storage::{
    save, DescriptorPrecision, LoadedAtlas, MapFileMeta, MapToSave, SaveOptions, SaveReport,
    StorageError, StoredRig,
};

use super::atlas::Atlas;
use super::slam_system::{LoopClosing, Mapping};
use super::SlamSystem;

/// What a run does with a loaded map.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LoadedMapUse {
    /// Track and keep mapping on it (keyframes, points, loops, merges).
    ContinueMapping,
    /// Localise only: no keyframe, point or map is added, nothing moves.
    LocaliseOnly,
}

/// What the caller knows of how the map was made, written into the file.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct MapProvenance {
    /// The extractor settings, as text.
    pub extractor_settings: String,
    /// Hash of the model file (hex), if a model made the descriptors.
    pub model_hash: Option<String>,
    /// Hash of the place-recognition codebook (hex), if loop closing ran.
    pub codebook_hash: Option<String>,
}

/// Refuses a file made with another model, codebook or extractor.
fn check_provenance(
    path: &Path,
    meta: &MapFileMeta,
    extractor: &str,
    current: &MapProvenance,
) -> Result<(), StorageError> {
    let mismatch = |what: &'static str, file: &str, now: &str| StorageError::BuiltWithAnother {
        path: path.to_path_buf(),
        what,
        file_hash: file.to_string(),
        current_hash: now.to_string(),
    };
    if meta.extractor != extractor {
        return Err(mismatch("extractor", &meta.extractor, extractor));
    }
    for (what, file, now) in [
        ("model", &meta.model_hash, &current.model_hash),
        ("codebook", &meta.codebook_hash, &current.codebook_hash),
    ] {
        if let (Some(file), Some(now)) = (file, now) {
            if file != now {
                return Err(mismatch(what, file, now));
            }
        }
    }
    Ok(())
}

/// Whether two rigs are the same camera (sensor, intrinsics, baseline,
/// size): a monocular map has no metric scale, so it never serves a
/// stereo or RGB-D system, nor the other way round.
fn same_camera(a: &CameraRig, b: &CameraRig) -> bool {
    let close = |x: f64, y: f64| (x - y).abs() <= 1e-6 * x.abs().max(y.abs()).max(1.0);
    a.sensor == b.sensor
        && close(a.camera.fx, b.camera.fx)
        && close(a.camera.fy, b.camera.fy)
        && close(a.camera.cx, b.camera.cx)
        && close(a.camera.cy, b.camera.cy)
        && close(a.baseline, b.baseline)
        && a.width == b.width
        && a.height == b.height
}

impl SlamSystem {
    /// Starts over on a loaded atlas (`path` names the file in errors):
    /// its maps replace this system's, the active one is activated (the
    /// next frame relocalises against it, through the keyframe database
    /// when loop closing is on, rebuilt here from the keyframes), and the
    /// frame records start empty. Refused, with nothing changed, when the
    /// file was made with another extractor, model or codebook than
    /// `current` names, or with another camera.
    ///
    /// With [`LoadedMapUse::LocaliseOnly`] tracking never inserts a
    /// keyframe nor starts a new map, so local mapping and loop closing
    /// have nothing to do and the maps are never changed (the points'
    /// visibility statistics excepted).
    pub fn load_map(
        &mut self,
        path: &Path,
        loaded: LoadedAtlas,
        current: &MapProvenance,
        use_: LoadedMapUse,
    ) -> Result<(), SlamError> {
        check_provenance(path, &loaded.meta, self.extractor_name(), current)?;
        let rig = CameraRig::from(&loaded.meta.rig);
        if !same_camera(&rig, &self.rig) {
            return Err(StorageError::BuiltWithAnother {
                path: path.to_path_buf(),
                what: "camera",
                file_hash: format!("{:?}", loaded.meta.rig),
                current_hash: format!("{:?}", StoredRig::from(&self.rig)),
            }
            .into());
        }
        let maps: Vec<_> = loaded
            .maps
            .into_iter()
            .map(|m| (m.index, m.first_frame, m.merged_into, m.map))
            .collect();
        let atlas = Atlas::from_loaded(maps, loaded.meta.active_map).ok_or_else(|| {
            StorageError::Corrupt {
                path: path.to_path_buf(),
                reason: "the atlas's map indices or active map do not fit".into(),
            }
        })?;
        let threaded = matches!(self.mapping, Mapping::Thread { .. });
        self.finish()?;
        if let Mapping::Inline(mapper) = &mut self.mapping {
            *mapper = mapper.fresh();
        }
        self.atlas = atlas;
        self.records.clear();
        self.loop_log = Default::default();
        self.loop_inbox.clear();
        if let Some(LoopClosing::Inline(stage)) = self.loop_closing.as_mut() {
            let guards = self
                .atlas
                .maps()
                .iter()
                .map(|m| m.map.read().map(|g| (m.index, g)))
                .collect::<Result<Vec<_>, _>>()
                .map_err(|_| SlamError::PoisonedMap)?;
            let maps: Vec<_> = guards.iter().map(|(i, g)| (*i, &**g)).collect();
            stage.index_loaded(&maps, self.atlas.active().index)?;
        }
        self.tracker
            .set_localisation_only(use_ == LoadedMapUse::LocaliseOnly);
        self.tracker.start_lost();
        if threaded {
            self.spawn_mapping_thread()?;
        }
        Ok(())
    }

    /// Saves every atlas map to `path` (atomically: the previous file stays
    /// whole until the new one is complete), descriptors in `precision`.
    /// Call [`Self::finish`] first for the final map; a save mid-run
    /// stores the maps as they are between two locked steps.
    pub fn save_map(
        &self,
        path: &Path,
        provenance: &MapProvenance,
        precision: DescriptorPrecision,
        options: SaveOptions,
    ) -> Result<SaveReport, SlamError> {
        let guards = self
            .atlas
            .maps()
            .iter()
            .map(|m| m.map.read().map_err(|_| SlamError::PoisonedMap))
            .collect::<Result<Vec<_>, _>>()?;
        let maps: Vec<MapToSave<'_>> = self
            .atlas
            .maps()
            .iter()
            .zip(&guards)
            .map(|(entry, guard)| MapToSave {
                index: entry.index,
                first_frame: entry.first_frame,
                merged_into: entry.merged_into,
                map: guard,
            })
            .collect();
        let meta = MapFileMeta {
            spslam_version: env!("CARGO_PKG_VERSION").to_string(),
            extractor: self.extractor_name().to_string(),
            extractor_settings: provenance.extractor_settings.clone(),
            model_hash: provenance.model_hash.clone(),
            codebook_hash: provenance.codebook_hash.clone(),
            rig: StoredRig::from(&self.rig),
            precision,
            active_map: self.atlas.active().index,
        };
        Ok(save(path, &meta, &maps, options)?)
    }
}
