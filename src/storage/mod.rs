//! Map storage: the whole atlas saved to one checked file and loaded back
//! (see `format` for the layout and the checks).
//!
//! - [`save`]: atomic (temporary file, sync, rename); descriptors in
//!   [`DescriptorPrecision::F32`], `F16` (the default) or `U8`;
//! - [`load`]: every fault is a [`StorageError`] naming the file and what
//!   is wrong; a map is returned only whole and consistent;
//! - [`peek`]: the metadata and sizes, for `spslam map info`.
//!
//! Layers: storage reads and builds [`crate::map::Map`]s; the system layer
//! decides what to save and what to do with a loaded atlas.

mod checksum;
mod descriptors;
mod error;
mod file;
mod format;
mod half;

pub use checksum::crc32;
pub use descriptors::{DescriptorPrecision, StoredDescriptors};
pub use error::StorageError;
pub use file::{load, save, temporary_path, SaveOptions, SaveReport};
pub use format::{
    decode, encode, peek, LoadedAtlas, LoadedMap, MapFileMeta, MapToSave, StoredAtlas, StoredMap,
    StoredRig, FORMAT_VERSION, HEADER_LEN, MAGIC,
};
