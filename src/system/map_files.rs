//! Saving the atlas to a map file (`crate::storage`): a snapshot of every
//! map under its read lock, with what the caller knows of the extractor,
//! model and codebook.

use std::path::Path;

use crate::error::SlamError;
use crate::storage::{
    save, DescriptorPrecision, MapFileMeta, MapToSave, SaveOptions, SaveReport, StoredRig,
};

use super::StereoSlam;

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

impl StereoSlam {
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
