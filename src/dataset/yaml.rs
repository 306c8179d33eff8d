//! A minimal line-based reader for the flat YAML of EuRoC `sensor.yaml` files:
//! `key: value`, one level of nested maps (`T_BS:` / `  data: […]`), flow
//! lists that may span lines, `#` comments and `%YAML` directives. Not a
//! general YAML parser.

use std::path::{Path, PathBuf};

use super::error::{DatasetError, Result};
use super::text::{parse_f64, read_text};

/// A parsed file: its entries, keyed by dotted path (`T_BS.data`).
pub(crate) struct YamlDoc {
    path: PathBuf,
    entries: Vec<Entry>,
}

/// One `key: value`, with the value split by source line.
struct Entry {
    key: String,
    line: usize,
    /// `(line, text)` pieces of the value; several for a multi-line list.
    pieces: Vec<(usize, String)>,
}

impl YamlDoc {
    /// Reads and tokenises a file.
    pub(crate) fn from_file(path: &Path) -> Result<Self> {
        let text = read_text(path)?;
        let mut entries: Vec<Entry> = Vec::new();
        let mut parent = String::new();
        let mut open_list = false;
        for (i, raw) in text.lines().enumerate() {
            let number = i + 1;
            let content = raw.split('#').next().unwrap_or("").trim_end();
            let trimmed = content.trim_start();
            if trimmed.is_empty() || trimmed.starts_with('%') || trimmed.starts_with("---") {
                continue;
            }
            if open_list {
                if let Some(entry) = entries.last_mut() {
                    entry.pieces.push((number, trimmed.to_string()));
                }
                open_list = !trimmed.contains(']');
                continue;
            }
            let (key, value) = trimmed.split_once(':').ok_or_else(|| {
                DatasetError::row(
                    path,
                    number,
                    format!("expected `key: value`, got `{trimmed}`"),
                )
            })?;
            let key = key.trim();
            let value = value.trim();
            let full_key = if content.len() == trimmed.len() {
                parent = key.to_string();
                key.to_string()
            } else {
                format!("{parent}.{key}")
            };
            open_list = value.starts_with('[') && !value.contains(']');
            entries.push(Entry {
                key: full_key,
                line: number,
                pieces: vec![(number, value.to_string())],
            });
        }
        if open_list {
            let line = entries.last().map_or(0, |e| e.line);
            return Err(DatasetError::row(
                path,
                line,
                "list `[` is never closed by `]`",
            ));
        }
        Ok(Self {
            path: path.to_path_buf(),
            entries,
        })
    }

    fn entry(&self, key: &str) -> Result<&Entry> {
        self.entries
            .iter()
            .find(|e| e.key == key)
            .ok_or_else(|| DatasetError::MissingKey {
                path: self.path.clone(),
                key: key.to_string(),
            })
    }

    /// A scalar value as text, with its line.
    pub(crate) fn text(&self, key: &str) -> Result<(&str, usize)> {
        let e = self.entry(key)?;
        let value = e.pieces.first().map_or("", |(_, v)| v.as_str());
        Ok((value.trim_matches(|c| c == '"' || c == '\''), e.line))
    }

    /// A non-negative integer value.
    pub(crate) fn integer(&self, key: &str) -> Result<u32> {
        let (value, line) = self.text(key)?;
        value.parse().map_err(|_| {
            DatasetError::row(
                &self.path,
                line,
                format!("{key}: `{value}` is not a non-negative integer"),
            )
        })
    }

    /// A flow list of exactly `n` numbers, e.g. `[1.0, 2.0]`.
    pub(crate) fn numbers(&self, key: &str, n: usize) -> Result<Vec<f64>> {
        let e = self.entry(key)?;
        let joined: String = e.pieces.iter().map(|(_, p)| p.as_str()).collect();
        if !joined.starts_with('[') || !joined.ends_with(']') {
            return Err(DatasetError::row(
                &self.path,
                e.line,
                format!("{key}: expected a list `[…]` of {n} numbers"),
            ));
        }
        let mut values = Vec::with_capacity(n);
        for (line, piece) in &e.pieces {
            for item in piece.split(',') {
                let item = item
                    .trim()
                    .trim_start_matches('[')
                    .trim_end_matches(']')
                    .trim();
                if item.is_empty() {
                    continue;
                }
                let field = format!("{key}[{}]", values.len());
                values.push(parse_f64(&self.path, *line, &field, item)?);
            }
        }
        if values.len() != n {
            return Err(DatasetError::row(
                &self.path,
                e.line,
                format!("{key}: {} numbers, expected {n}", values.len()),
            ));
        }
        Ok(values)
    }

    /// The file this was read from.
    pub(crate) fn path(&self) -> &Path {
        &self.path
    }
}
