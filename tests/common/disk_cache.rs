//! The disk half of the tests' caches of rendered frames and extracted
//! features: one folder (`SPSLAM_TEST_CACHE`, set by `tools/run_tests.py`
//! and emptied at the start of each of its runs) shared by the test
//! processes of one run, so a frame or a feature set computed by one test
//! is read back by the next instead of being computed again. Without the
//! variable (a plain `cargo test`) nothing touches the disk.
//!
//! Entries are written to a temporary name and renamed, so a process never
//! reads half an entry. An entry that cannot be read or decoded is a miss,
//! never an error: the caller computes it again.
//!
//! [`get_or_compute`] claims an entry before computing it (a `.claim` file
//! made with `create_new`, holding the process id), so two tests that walk
//! the same frames side by side (they start together, longest first) split
//! the work: the one behind waits for the entry instead of computing it
//! again. A claim whose process has ended is taken over; a wait longer than
//! [`CLAIM_PATIENCE`] computes the entry anyway. Every entry computed is
//! logged in `computed.log` (kind, key, process), so a run can count the
//! entries computed twice.

use std::collections::hash_map::DefaultHasher;
use std::hash::{Hash, Hasher};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// How long a test waits for an entry another process claimed before it
/// computes the entry itself (a 480×360 SuperPoint extraction takes well
/// under a second; a render about 0.1 s).
const CLAIM_PATIENCE: Duration = Duration::from_secs(120);

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

/// Stores an entry (when the disk cache is on); a failed write only
/// loses the entry.
fn store(kind: &str, key: (u64, u64), bytes: &[u8]) {
    let Some(path) = path(kind, key) else {
        return;
    };
    let temporary = path.with_extension(format!("{}.partial", std::process::id()));
    if std::fs::write(&temporary, bytes).is_ok() && std::fs::rename(&temporary, &path).is_err() {
        let _ = std::fs::remove_file(&temporary);
    }
}

/// The entry `key` of `kind`: read back when the run has it (and it
/// decodes), else computed by `compute` and stored, once across the run's
/// processes (see the module's claims). Without the disk cache (a plain
/// `cargo test`) this is `compute()`.
pub fn get_or_compute<T, E>(
    kind: &str,
    key: (u64, u64),
    decode: impl Fn(&[u8]) -> Option<T>,
    encode: impl Fn(&T) -> Vec<u8>,
    compute: impl FnOnce() -> Result<T, E>,
) -> Result<T, E> {
    let Some(path) = path(kind, key) else {
        return compute();
    };
    let claim = path.with_extension("claim");
    let read = || std::fs::read(&path).ok().and_then(|b| decode(&b));
    let started = Instant::now();
    let claimed = loop {
        if let Some(value) = read() {
            return Ok(value);
        }
        if try_claim(&claim) {
            break true;
        }
        if started.elapsed() >= CLAIM_PATIENCE {
            break false;
        }
        if !claim_holder_alive(&claim) {
            let _ = std::fs::remove_file(&claim);
            continue;
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    // Another process may have stored it between the read and the claim.
    if let Some(value) = read() {
        if claimed {
            let _ = std::fs::remove_file(&claim);
        }
        return Ok(value);
    }
    let computed = compute();
    if let Ok(value) = &computed {
        store(kind, key, &encode(value));
        log_computed(kind, key);
    }
    if claimed {
        let _ = std::fs::remove_file(&claim);
    }
    computed
}

/// Makes the claim file (with this process's id); false when it exists.
fn try_claim(claim: &Path) -> bool {
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(claim)
        .and_then(|mut f| write!(f, "{}", std::process::id()))
        .is_ok()
}

/// Whether the process named in the claim file still runs (true while the
/// file is being written and has no id yet).
fn claim_holder_alive(claim: &Path) -> bool {
    match std::fs::read_to_string(claim) {
        Ok(text) => match text.trim().parse::<u32>() {
            Ok(pid) => Path::new(&format!("/proc/{pid}")).exists(),
            Err(_) => true,
        },
        // Gone: released (the entry is there) or taken over.
        Err(_) => true,
    }
}

/// Appends `kind key pid` to the run's `computed.log`.
fn log_computed(kind: &str, key: (u64, u64)) {
    let Some(dir) = std::env::var_os("SPSLAM_TEST_CACHE") else {
        return;
    };
    let line = format!(
        "{kind} {:016x}{:016x} {}\n",
        key.0,
        key.1,
        std::process::id()
    );
    if let Ok(mut f) = std::fs::OpenOptions::new()
        .append(true)
        .create(true)
        .open(Path::new(&dir).join("computed.log"))
    {
        let _ = f.write_all(line.as_bytes());
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
