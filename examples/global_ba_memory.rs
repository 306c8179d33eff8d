//! The working set of a global bundle adjustment on a saved map: loads a
//! map file (`spslam run --save-map`), then takes the global BA's three
//! steps on its largest map as `spslam run` does after a loop correction
//! (`loop_closing::global_ba`: snapshot, solve, apply) and prints the
//! allocator's live heap after each, and the highest live heap seen while
//! the solve ran (sampled every 2 ms on another thread). Usage:
//! `cargo run --release --example global_ba_memory MAP_FILE`
//!
//! What it answers: how much memory a global BA adds to a run at a given
//! map size (`EVALUATION.md`, 'Soak'). glibc only (`mallinfo2`).

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use spslam::camera::CameraRig;
use spslam::loop_closing::{apply_global_ba, snapshot_global_ba, solve_global_ba};

/// The allocator's live heap, MiB (0 where the C library is not glibc).
fn live_mib() -> f64 {
    spslam::ffi::heap_usage().map_or(0.0, |h| h.in_use_mib)
}

fn main() -> ExitCode {
    let Some(path) = std::env::args_os().nth(1).map(PathBuf::from) else {
        eprintln!("usage: global_ba_memory MAP_FILE");
        return ExitCode::from(2);
    };
    let atlas = match spslam::storage::load(&path) {
        Ok(atlas) => atlas,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
    };
    let rig = CameraRig::from(&atlas.meta.rig);
    let Some(mut loaded) = atlas
        .maps
        .into_iter()
        .max_by_key(|m| m.map.keyframe_count())
    else {
        eprintln!("error: {} holds no map", path.display());
        return ExitCode::FAILURE;
    };
    let map = &mut loaded.map;
    println!(
        "map {}: {} keyframes, {} points",
        loaded.index,
        map.keyframe_count(),
        map.map_point_count()
    );
    let base = live_mib();
    println!("live heap with the map loaded: {base:.1} MiB");

    let start = Instant::now();
    let Some(snapshot) = snapshot_global_ba(map, &rig) else {
        eprintln!("error: the map has fewer than two keyframes or no observation");
        return ExitCode::FAILURE;
    };
    let after_snapshot = live_mib();
    println!(
        "snapshot: +{:.1} MiB ({:.0} ms)",
        after_snapshot - base,
        start.elapsed().as_secs_f64() * 1e3
    );

    // The highest live heap while the solve runs, from a sampling thread.
    let done = Arc::new(AtomicBool::new(false));
    let peak = Arc::new(Mutex::new(after_snapshot));
    let sampler = {
        let (done, peak) = (done.clone(), peak.clone());
        std::thread::spawn(move || {
            while !done.load(Ordering::Relaxed) {
                let now = live_mib();
                if let Ok(mut p) = peak.lock() {
                    *p = p.max(now);
                }
                std::thread::sleep(Duration::from_millis(2));
            }
        })
    };
    let never = AtomicBool::new(false);
    let start = Instant::now();
    let solved = solve_global_ba(snapshot, &never);
    let solve_ms = start.elapsed().as_secs_f64() * 1e3;
    done.store(true, Ordering::Relaxed);
    let _ = sampler.join();
    let solved = match solved {
        Ok(solved) => solved,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
    };
    let summary = solved.summary();
    let peak = peak.lock().map_or(f64::NAN, |p| *p);
    println!(
        "solve: {} keyframes, {} points, {} observations, {solve_ms:.0} ms; \
         live heap at most +{:.1} MiB over the map, +{:.1} MiB when it ended",
        summary.keyframes,
        summary.points,
        summary.observations,
        peak - base,
        live_mib() - base
    );
    let summary = apply_global_ba(map, solved);
    println!(
        "applied: +{:.1} MiB over the map (aborted: {})",
        live_mib() - base,
        summary.aborted
    );
    ExitCode::SUCCESS
}
