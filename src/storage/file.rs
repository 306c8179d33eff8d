//! Saving atomically and loading map files.
//!
//! A save writes a temporary file next to the target, syncs it to disk,
//! renames it over the target and syncs the directory: a crash at any
//! point leaves either the previous file or the new one, never a mix.

use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};

use super::error::StorageError;
use super::format::{decode, encode, LoadedAtlas, MapFileMeta, MapToSave};

/// How to save.
#[derive(Debug, Clone, Copy, Default)]
pub struct SaveOptions {
    /// Test hook: write only this many bytes of the temporary file, then
    /// fail as a crash would ([`StorageError::Interrupted`]). `None` in
    /// every real save.
    pub interrupt_after: Option<usize>,
}

/// What a save wrote.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SaveReport {
    /// Bytes in the file.
    pub bytes: u64,
    /// Live keyframes over all maps.
    pub keyframes: usize,
    /// Live points over all maps.
    pub points: usize,
}

fn io<'a>(
    path: &'a Path,
    action: &'static str,
) -> impl FnOnce(std::io::Error) -> StorageError + 'a {
    move |source| StorageError::Io {
        path: path.to_path_buf(),
        action,
        source,
    }
}

/// The temporary file a save of `path` writes first.
pub fn temporary_path(path: &Path) -> PathBuf {
    let mut name = path
        .file_name()
        .map(|n| n.to_os_string())
        .unwrap_or_default();
    name.push(".saving");
    path.with_file_name(name)
}

/// Saves `maps` with `meta` to `path` atomically (see the module's docs).
pub fn save(
    path: &Path,
    meta: &MapFileMeta,
    maps: &[MapToSave<'_>],
    options: SaveOptions,
) -> Result<SaveReport, StorageError> {
    let bytes = encode(meta, maps).map_err(|reason| StorageError::Corrupt {
        path: path.to_path_buf(),
        reason: format!("cannot encode the map: {reason}"),
    })?;
    let temporary = temporary_path(path);
    let mut file = File::create(&temporary).map_err(io(&temporary, "create"))?;
    if let Some(n) = options.interrupt_after {
        let n = n.min(bytes.len());
        file.write_all(&bytes[..n])
            .map_err(io(&temporary, "write"))?;
        return Err(StorageError::Interrupted {
            path: path.to_path_buf(),
            written: n,
        });
    }
    file.write_all(&bytes).map_err(io(&temporary, "write"))?;
    file.sync_all().map_err(io(&temporary, "sync"))?;
    drop(file);
    std::fs::rename(&temporary, path).map_err(io(path, "rename"))?;
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        // Makes the rename durable; a directory that cannot be opened for
        // syncing (some file systems) does not undo the save.
        if let Ok(d) = File::open(dir) {
            let _ = d.sync_all();
        }
    }
    Ok(SaveReport {
        bytes: bytes.len() as u64,
        keyframes: maps.iter().map(|m| m.map.keyframe_count()).sum(),
        points: maps.iter().map(|m| m.map.map_point_count()).sum(),
    })
}

/// Loads and checks a map file.
pub fn load(path: &Path) -> Result<LoadedAtlas, StorageError> {
    let bytes = std::fs::read(path).map_err(io(path, "read"))?;
    decode(path, &bytes)
}
