//! Fuzzing the map loader with mutated real map files: an ORB map (binary
//! descriptors, f16 file) and a SuperPoint map (float descriptors, 700
//! keypoints per frame, 3 frames, f16 and u8 files), 10,000 mutations in all:
//!
//! - bit flips and overwritten byte runs in the payload with the checksum
//!   recomputed, so they reach the decoder and the consistency checks
//!   (most of the corpus);
//! - the same without recomputing it (checksum errors);
//! - truncations, another version, another announced length.
//!
//! Every mutated file must load or give a typed error: no panic (caught
//! and counted) and no allocation beyond the file's size (a counting
//! allocator: the peak during one decode stays under 64 bytes per file
//! byte plus 64 MiB). Outcomes are counted by kind (`--nocapture`).
//!
//! More mutations: `SPSLAM_FUZZ_CASES=100000 cargo test --release --test
//! map_storage_fuzz -- --nocapture` (spread over the three files as below).

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};

use common::rng::Rng;
use spslam::storage::{crc32, decode, DescriptorPrecision, SaveOptions, StorageError, HEADER_LEN};
use spslam::system::{MapProvenance, SlamSystem};

/// Counts live bytes and their peak.
struct CountingAllocator;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let live = LIVE.fetch_add(layout.size(), Ordering::Relaxed) + layout.size();
        PEAK.fetch_max(live, Ordering::Relaxed);
        // SAFETY: forwards the caller's layout to the system allocator.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        // SAFETY: `ptr` came from `alloc` with this layout.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

fn ok<T, E: std::fmt::Display>(r: Result<T, E>) -> T {
    r.unwrap_or_else(|e| panic!("{e}"))
}

/// The bytes of `slam`'s map saved with `precision`.
fn map_file(slam: &SlamSystem, precision: DescriptorPrecision, tag: &str) -> Vec<u8> {
    let path = std::env::temp_dir().join(format!("spslam-fuzz-{tag}-{}.spmap", std::process::id()));
    ok(slam.save_map(
        &path,
        &MapProvenance::default(),
        precision,
        SaveOptions::default(),
    ));
    let bytes = ok(std::fs::read(&path));
    let _ = std::fs::remove_file(&path);
    bytes
}

/// Writes a payload's checksum into its header.
fn fix_checksum(bytes: &mut [u8]) {
    if bytes.len() >= HEADER_LEN {
        let crc = crc32(&bytes[HEADER_LEN..]);
        bytes[20..24].copy_from_slice(&crc.to_le_bytes());
    }
}

/// One mutation of `original`, by kind.
fn mutate(original: &[u8], rng: &mut Rng) -> (Vec<u8>, &'static str) {
    let mut bytes = original.to_vec();
    let payload = HEADER_LEN..bytes.len();
    let pick = |rng: &mut Rng, range: &std::ops::Range<usize>| {
        range.start + (rng.next_u64() as usize) % (range.end - range.start).max(1)
    };
    let kind = rng.next_u64() % 100;
    let label = match kind {
        0..=49 => {
            for _ in 0..1 + rng.next_u64() % 4 {
                let at = pick(rng, &payload);
                bytes[at] ^= 1 << (rng.next_u64() % 8);
            }
            fix_checksum(&mut bytes);
            "bit flips, checksum fixed"
        }
        50..=69 => {
            let at = pick(rng, &payload);
            let run = 1 + (rng.next_u64() % 16) as usize;
            for b in bytes.iter_mut().skip(at).take(run) {
                *b = rng.next_u64() as u8;
            }
            fix_checksum(&mut bytes);
            "byte run overwritten, checksum fixed"
        }
        70..=79 => {
            let at = pick(rng, &payload);
            bytes[at] ^= 1 << (rng.next_u64() % 8);
            "bit flip"
        }
        80..=89 => {
            let keep = (rng.next_u64() as usize) % bytes.len();
            bytes.truncate(keep);
            "truncated"
        }
        90..=94 => {
            let version = (rng.next_u64() % 1000) as u32 + 2;
            bytes[8..12].copy_from_slice(&version.to_le_bytes());
            "another version"
        }
        _ => {
            let length = rng.next_u64() >> (rng.next_u64() % 64);
            bytes[12..20].copy_from_slice(&length.to_le_bytes());
            "another length"
        }
    };
    (bytes, label)
}

/// The outcome's name.
fn outcome(result: &Result<spslam::storage::LoadedAtlas, StorageError>) -> &'static str {
    match result {
        Ok(_) => "loaded",
        Err(StorageError::NotAMapFile { .. }) => "not a map file",
        Err(StorageError::UnsupportedVersion { .. }) => "unsupported version",
        Err(StorageError::Truncated { .. }) => "truncated",
        Err(StorageError::ChecksumMismatch { .. }) => "checksum mismatch",
        Err(StorageError::Corrupt { .. }) => "corrupt payload",
        Err(StorageError::Inconsistent { .. }) => "inconsistent map",
        Err(_) => "other error",
    }
}

#[test]
fn ten_thousand_mutated_map_files_load_or_fail_with_a_typed_error() {
    let test = "ten_thousand_mutated_map_files_load_or_fail_with_a_typed_error";
    if !common::model_available(test) {
        return;
    }
    let total: usize = std::env::var("SPSLAM_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10_000);
    let orb = common::map_files::orb_system(16);
    let superpoint = common::map_files::superpoint_system(3, 700);
    let files = [
        (
            "orb f16",
            map_file(&orb, DescriptorPrecision::F16, "orb"),
            4,
        ),
        (
            "superpoint f16",
            map_file(&superpoint, DescriptorPrecision::F16, "sp16"),
            3,
        ),
        (
            "superpoint u8",
            map_file(&superpoint, DescriptorPrecision::U8, "sp8"),
            3,
        ),
    ];
    let path = Path::new("mutated.spmap");
    // Panics are caught and counted, not printed one by one.
    std::panic::set_hook(Box::new(|_| {}));
    let mut rng = Rng::new(20261125);
    let mut counts: BTreeMap<(&str, &str, &str), usize> = BTreeMap::new();
    let mut panics = Vec::new();
    let mut worst_ratio = 0.0f64;
    let mut done = 0;
    for (name, original, share) in &files {
        let loaded = decode(path, original).map(|a| a.maps[0].map.keyframe_count());
        assert!(
            matches!(loaded, Ok(k) if k > 0),
            "{name}: the unmutated file does not load a map with keyframes: {loaded:?}"
        );
        let cases = total * share / 10;
        for case in 0..cases {
            let (bytes, kind) = mutate(original, &mut rng);
            let base = LIVE.load(Ordering::Relaxed);
            PEAK.store(base, Ordering::Relaxed);
            let result = std::panic::catch_unwind(|| decode(path, &bytes));
            let peak = PEAK.load(Ordering::Relaxed).saturating_sub(base);
            let limit = 64 * bytes.len() + (64 << 20);
            worst_ratio = worst_ratio.max(peak as f64 / bytes.len().max(1) as f64);
            assert!(
                peak <= limit,
                "{name} case {case} ({kind}): {peak} bytes allocated for a {}-byte file",
                bytes.len()
            );
            match result {
                Ok(r) => *counts.entry((name, kind, outcome(&r))).or_default() += 1,
                Err(_) => panics.push((*name, case, kind)),
            }
            done += 1;
        }
        eprintln!("{name}: {} bytes, {cases} mutations", original.len());
    }
    let _ = std::panic::take_hook();
    for ((name, kind, result), n) in &counts {
        eprintln!("  {name:15} {kind:38} -> {result:20} {n}");
    }
    eprintln!(
        "{done} mutated files, {} panics; peak allocation at most {worst_ratio:.1} bytes per file byte",
        panics.len()
    );
    assert!(done >= total * 9 / 10 && done > 0);
    assert!(panics.is_empty(), "panics: {panics:?}");
    // The fuzzing reaches the decoder and the checks, not only the checksum.
    for deep in ["corrupt payload", "inconsistent map"] {
        assert!(
            counts.iter().any(|((_, _, r), _)| *r == deep),
            "no mutation reached \"{deep}\""
        );
    }
}
