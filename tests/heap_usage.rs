//! `spslam::ffi::heap_usage` (glibc's `mallinfo2`, which `spslam run
//! --memory-log` writes next to the resident memory): a block allocated is
//! counted as in use, and freed it is no longer. Alone in its test binary,
//! so that no other test allocates meanwhile.

#[test]
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn the_live_heap_counts_what_is_allocated_and_not_what_is_freed() {
    const BLOCK: usize = 64 * 1024; // below glibc's mmap threshold: from the arena
    const BLOCKS: usize = 1600; // 100 MiB
    let mib = (BLOCK * BLOCKS) as f64 / (1024.0 * 1024.0);
    let before = spslam::ffi::heap_usage().expect("glibc reports its heap");
    let blocks: Vec<Vec<u8>> = (0..BLOCKS).map(|i| vec![(i % 251) as u8; BLOCK]).collect();
    let held = spslam::ffi::heap_usage().expect("glibc reports its heap");
    let grown = held.in_use_mib - before.in_use_mib;
    // Each block's header and the vector of blocks add a little; 2 % is
    // the margin.
    assert!(
        (grown - mib).abs() < 0.02 * mib,
        "{mib} MiB allocated, the live heap grew by {grown:.2} MiB"
    );
    drop(blocks);
    let after = spslam::ffi::heap_usage().expect("glibc reports its heap");
    let shrunk = held.in_use_mib - after.in_use_mib;
    assert!(
        (shrunk - mib).abs() < 0.02 * mib,
        "{mib} MiB freed, the live heap shrank by {shrunk:.2} MiB"
    );
    // What glibc did not return at once (the top of the heap beyond its
    // trim threshold goes back) is counted as freed and held, never below 0.
    assert!(after.free_held_mib >= 0.0);
}
