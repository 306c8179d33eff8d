//! Typed lookups in an OpenCV `FileStorage`, with errors naming file and key.

use std::path::{Path, PathBuf};

use opencv::core::FileStorage_Mode;
use opencv::core::{FileNode, FileNodeTraitConst, FileStorage, FileStorageTraitConst};

use super::error::{Result, SettingsError};

/// An opened settings file.
pub(super) struct SettingsReader {
    path: PathBuf,
    storage: FileStorage,
}

impl SettingsReader {
    /// Opens `path` with OpenCV's FileStorage.
    pub(super) fn open(path: &Path) -> Result<Self> {
        if !path.is_file() {
            return Err(SettingsError::NotFound {
                path: path.to_path_buf(),
            });
        }
        let parse_error = |e: opencv::Error| SettingsError::Parse {
            path: path.to_path_buf(),
            reason: e.message,
        };
        let storage =
            FileStorage::new(path, FileStorage_Mode::READ as i32, "").map_err(parse_error)?;
        if !storage.is_opened().map_err(parse_error)? {
            return Err(SettingsError::Parse {
                path: path.to_path_buf(),
                reason: "FileStorage could not open it".into(),
            });
        }
        Ok(Self {
            path: path.to_path_buf(),
            storage,
        })
    }

    /// The file's path.
    pub(super) fn path(&self) -> &Path {
        &self.path
    }

    /// The first of `keys` present in the file, with its node.
    fn node(&self, keys: &[&str]) -> Result<Option<(String, FileNode)>> {
        for key in keys {
            let node = self.storage.get(key).map_err(|e| SettingsError::Parse {
                path: self.path.clone(),
                reason: e.message,
            })?;
            if !node.is_none().unwrap_or(true) {
                return Ok(Some(((*key).to_string(), node)));
            }
        }
        Ok(None)
    }

    fn wrong_type(&self, key: &str, expected: &'static str) -> SettingsError {
        SettingsError::WrongType {
            path: self.path.clone(),
            key: key.to_string(),
            expected,
        }
    }

    /// A number under any of `keys`, if present.
    pub(super) fn optional_f64(&self, keys: &[&str]) -> Result<Option<f64>> {
        let Some((key, node)) = self.node(keys)? else {
            return Ok(None);
        };
        let numeric = node.is_real().unwrap_or(false) || node.is_int().unwrap_or(false);
        if !numeric {
            return Err(self.wrong_type(&key, "a number"));
        }
        let value = node.real().map_err(|_| self.wrong_type(&key, "a number"))?;
        if !value.is_finite() {
            return Err(self.invalid(&key, value, "not a finite number"));
        }
        Ok(Some(value))
    }

    /// An integer under any of `keys`, if present.
    pub(super) fn optional_i64(&self, keys: &[&str]) -> Result<Option<i64>> {
        let Some((key, node)) = self.node(keys)? else {
            return Ok(None);
        };
        if !node.is_int().unwrap_or(false) {
            return Err(self.wrong_type(&key, "an integer"));
        }
        let value = node
            .to_i32()
            .map_err(|_| self.wrong_type(&key, "an integer"))?;
        Ok(Some(i64::from(value)))
    }

    /// A string under any of `keys`, if present.
    pub(super) fn optional_string(&self, keys: &[&str]) -> Result<Option<String>> {
        let Some((key, node)) = self.node(keys)? else {
            return Ok(None);
        };
        if !node.is_string().unwrap_or(false) {
            return Err(self.wrong_type(&key, "a string"));
        }
        node.string()
            .map(Some)
            .map_err(|_| self.wrong_type(&key, "a string"))
    }

    /// A required number under any of `keys`.
    pub(super) fn required_f64(&self, keys: &[&str], hint: &str) -> Result<f64> {
        self.optional_f64(keys)?
            .ok_or_else(|| self.missing(keys, hint))
    }

    /// The error for a missing key.
    pub(super) fn missing(&self, keys: &[&str], hint: &str) -> SettingsError {
        SettingsError::Missing {
            path: self.path.clone(),
            key: keys.first().copied().unwrap_or("").to_string(),
            hint: hint.to_string(),
        }
    }

    /// The error for an out-of-range value.
    pub(super) fn invalid(
        &self,
        key: &str,
        value: impl std::fmt::Display,
        reason: &'static str,
    ) -> SettingsError {
        SettingsError::Invalid {
            path: self.path.clone(),
            key: key.to_string(),
            value: value.to_string(),
            reason,
        }
    }
}
