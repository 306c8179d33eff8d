//! The disk half of the tests' caches of rendered frames and extracted
//! features: one folder (`SPSLAM_TEST_CACHE`, set by `tools/run_tests.py`
//! and emptied at the start of each of its runs) shared by the test
//! processes of one run, so a frame or a feature set computed by one test
//! is read back by the next instead of being computed again. Without the
//! variable (a plain `cargo test`) nothing touches the disk.
//!
//! Entries are written to a temporary name and renamed, so a process never
//! reads half an entry; two processes computing the same entry at once
//! both write the same bytes. An entry that cannot be read or decoded is
//! a miss, never an error: the caller computes it again.

use std::collections::hash_map::DefaultHasher;
use std::hash::{Hash, Hasher};
use std::path::PathBuf;

/// Two independent 64-bit hashes of what `feed` writes (a collision of
/// both is not a concern at the tests' few thousand entries).
pub fn key(feed: impl Fn(&mut DefaultHasher)) -> (u64, u64) {
    let hash = |salt: u64| {
        let mut h = DefaultHasher::new();
        salt.hash(&mut h);
        feed(&mut h);
        h.finish()
    };
    (hash(0x5eed_0001), hash(0x5eed_0002))
}

fn path(kind: &str, key: (u64, u64)) -> Option<PathBuf> {
    let dir = std::env::var_os("SPSLAM_TEST_CACHE")?;
    Some(PathBuf::from(dir).join(format!("{kind}-{:016x}{:016x}", key.0, key.1)))
}

/// The entry's bytes, when the disk cache is on and has it.
pub fn load(kind: &str, key: (u64, u64)) -> Option<Vec<u8>> {
    std::fs::read(path(kind, key)?).ok()
}

/// Stores an entry (when the disk cache is on); a failed write only
/// loses the entry.
pub fn store(kind: &str, key: (u64, u64), bytes: &[u8]) {
    let Some(path) = path(kind, key) else {
        return;
    };
    let temporary = path.with_extension(format!("{}.partial", std::process::id()));
    if std::fs::write(&temporary, bytes).is_ok() && std::fs::rename(&temporary, &path).is_err() {
        let _ = std::fs::remove_file(&temporary);
    }
}

/// Little-endian writer of an entry.
#[derive(Default)]
pub struct Writer(pub Vec<u8>);

impl Writer {
    /// Appends a `u64`.
    pub fn u64(&mut self, v: u64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }

    /// Appends an `f64`.
    pub fn f64(&mut self, v: f64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }

    /// Appends an `f32`.
    pub fn f32(&mut self, v: f32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }

    /// Appends a length and the bytes.
    pub fn bytes(&mut self, v: &[u8]) {
        self.u64(v.len() as u64);
        self.0.extend_from_slice(v);
    }

    /// Appends a length and the floats.
    pub fn f32s(&mut self, v: &[f32]) {
        self.u64(v.len() as u64);
        for x in v {
            self.f32(*x);
        }
    }
}

/// Little-endian reader of an entry; `None` at the end of the bytes.
pub struct Reader<'a>(pub &'a [u8]);

impl Reader<'_> {
    fn take<const N: usize>(&mut self) -> Option<[u8; N]> {
        let (head, rest) = self.0.split_at_checked(N)?;
        self.0 = rest;
        head.try_into().ok()
    }

    /// Reads a `u64`.
    pub fn u64(&mut self) -> Option<u64> {
        self.take::<8>().map(u64::from_le_bytes)
    }

    /// Reads an `f64`.
    pub fn f64(&mut self) -> Option<f64> {
        self.take::<8>().map(f64::from_le_bytes)
    }

    /// Reads an `f32`.
    pub fn f32(&mut self) -> Option<f32> {
        self.take::<4>().map(f32::from_le_bytes)
    }

    /// Reads a length and that many bytes.
    pub fn bytes(&mut self) -> Option<Vec<u8>> {
        let n = usize::try_from(self.u64()?).ok()?;
        let (head, rest) = self.0.split_at_checked(n)?;
        self.0 = rest;
        Some(head.to_vec())
    }

    /// Reads a length and that many floats.
    pub fn f32s(&mut self) -> Option<Vec<f32>> {
        let n = usize::try_from(self.u64()?).ok()?;
        (0..n).map(|_| self.f32()).collect()
    }

    /// True when every byte was read.
    pub fn is_done(&self) -> bool {
        self.0.is_empty()
    }
}
