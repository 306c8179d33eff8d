//! Small helpers for the line-based text files of the datasets.

use std::path::{Path, PathBuf};

use super::error::{DatasetError, Result};

/// One non-empty, non-comment line of a text file.
pub(crate) struct Line<'a> {
    /// 1-based line number.
    pub number: usize,
    /// The line, trimmed.
    pub text: &'a str,
}

/// Reads a whole text file; a missing file is [`DatasetError::MissingFile`].
pub(crate) fn read_text(path: &Path) -> Result<String> {
    std::fs::read_to_string(path).map_err(|source| {
        if source.kind() == std::io::ErrorKind::NotFound {
            DatasetError::MissingFile {
                path: path.to_path_buf(),
            }
        } else {
            DatasetError::Io {
                path: path.to_path_buf(),
                source,
            }
        }
    })
}

/// The lines that carry data: trimmed, skipping blank lines and `#` comments.
pub(crate) fn data_lines(text: &str) -> impl Iterator<Item = Line<'_>> {
    text.lines()
        .enumerate()
        .map(|(i, l)| Line {
            number: i + 1,
            text: l.trim(),
        })
        .filter(|l| !l.text.is_empty() && !l.text.starts_with('#'))
}

/// Parses one number of a row, naming the field on failure.
pub(crate) fn parse_f64(path: &Path, line: usize, field: &str, s: &str) -> Result<f64> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| DatasetError::row(path, line, format!("{field}: `{s}` is not a number")))?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(DatasetError::row(
            path,
            line,
            format!("{field}: `{s}` is not finite"),
        ))
    }
}

/// Parses an integer nanosecond timestamp.
pub(crate) fn parse_ns(path: &Path, line: usize, s: &str) -> Result<u64> {
    s.trim().parse().map_err(|_| {
        DatasetError::row(
            path,
            line,
            format!("timestamp `{s}` is not an integer number of nanoseconds"),
        )
    })
}

/// Fails with [`DatasetError::MissingFolder`] unless `path` is a folder.
pub(crate) fn require_dir(path: &Path) -> Result<PathBuf> {
    if path.is_dir() {
        Ok(path.to_path_buf())
    } else {
        Err(DatasetError::MissingFolder {
            path: path.to_path_buf(),
        })
    }
}

/// Checks that `t` is strictly after `previous`.
pub(crate) fn require_increasing<T: PartialOrd + std::fmt::Display>(
    path: &Path,
    line: usize,
    previous: Option<T>,
    t: T,
) -> Result<()> {
    match previous {
        Some(p) if t <= p => Err(DatasetError::row(
            path,
            line,
            format!("timestamp {t} is not after the previous one ({p})"),
        )),
        _ => Ok(()),
    }
}

/// Nanoseconds to seconds.
pub(crate) fn ns_to_s(ns: u64) -> f64 {
    // Split to keep the sub-second part exact before the addition.
    (ns / 1_000_000_000) as f64 + (ns % 1_000_000_000) as f64 * 1e-9
}
