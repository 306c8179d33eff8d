//! Localisation in a saved map (SuperPoint int8, one level, 480×360, the
//! default codebook, local mapping inline):
//!
//! - the first lap of the synthetic block (plus the return to the start,
//!   where the loop closes) is mapped and saved (f16, the default);
//! - the second lap is localised against the loaded map: at least 95 % of
//!   the frames localised, no keyframe added, the map unchanged; position
//!   error against the first pass's estimate of the same place (the laps
//!   repeat the same poses) at most 5 cm at the median and 20 cm at the
//!   95th percentile; the error against the ground truth (which adds the
//!   map's own error) is printed;
//! - a kidnapped start in the middle of the saved map relocalises within
//!   3 frames;
//! - the same localisation (first 80 frames of the lap) from f32 and u8
//!   files, for the precision's effect (printed; u8 must still localise).

mod common;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use common::synthetic_slam::{cached_images, rig_of, small_sequence};
use spslam::dataset::synthetic::{SceneName, SyntheticSequence};
use spslam::loop_closing::LoopThresholds;
use spslam::optim::Se3;
use spslam::place::{default_codebook_for, Codebook};
use spslam::settings::ExtractorSettings;
use spslam::storage::{load, DescriptorPrecision, SaveOptions};
use spslam::system::{LoadedMapUse, MapProvenance, SlamSystem};
use spslam::tracking::{Frontend, TrackingState};

fn ok<T, E: std::fmt::Display>(r: Result<T, E>) -> T {
    r.unwrap_or_else(|e| panic!("{e}"))
}

/// A SuperPoint system with loop closing, mapping inline; its extractors
/// share the feature cache (the localisation runs see the same frames).
fn system(sequence: &SyntheticSequence) -> SlamSystem {
    let rig = rig_of(sequence);
    let config = ExtractorSettings::default().superpoint_config(1, 1);
    let sp = || Box::new(common::cached_extractor(config.clone()));
    let mut slam = SlamSystem::new(rig, Frontend::new(sp(), sp(), &rig));
    let codebook = ok(Codebook::load_for(&default_codebook_for(&config), &config));
    ok(slam.enable_loop_closing(Arc::new(codebook.vlad), LoopThresholds::default()));
    slam
}

fn process(slam: &mut SlamSystem, sequence: &SyntheticSequence, frames: std::ops::Range<usize>) {
    for i in frames {
        let (t, l, r) = cached_images(sequence, i);
        ok(slam.process(i, t, l.view(), r.view()));
    }
    ok(slam.finish());
}

/// Keyframes and points over the atlas.
fn counts(slam: &SlamSystem) -> (usize, usize) {
    slam.atlas().maps().iter().fold((0, 0), |(k, p), m| {
        let g = ok(m.map.read().map_err(|_| "poisoned"));
        (k + g.keyframe_count(), p + g.map_point_count())
    })
}

/// The loaded map, localisation only.
fn localiser(sequence: &SyntheticSequence, path: &Path) -> SlamSystem {
    let mut slam = system(sequence);
    let loaded = ok(load(path));
    ok(slam.load_map(
        path,
        loaded,
        &MapProvenance::default(),
        LoadedMapUse::LocaliseOnly,
    ));
    slam
}

fn percentile(sorted: &[f64], q: f64) -> f64 {
    let i = ((sorted.len() as f64 - 1.0) * q).round() as usize;
    sorted.get(i).copied().unwrap_or(f64::NAN)
}

/// Position errors of the localised frames (`offset` frames after the
/// mapped ones they repeat) against the first pass's estimates and
/// against the truth; the fraction localised.
fn errors(
    localised: &SlamSystem,
    first_pass: &[(f64, Se3)],
    truth: impl Fn(usize) -> nalgebra::Vector3<f64>,
    offset: usize,
) -> (Vec<f64>, Vec<f64>, f64) {
    let poses = ok(localised.trajectory());
    let (mut to_map, mut to_truth) = (Vec::new(), Vec::new());
    let records = localised.records();
    for (record, (_, pose)) in records.iter().zip(&poses) {
        if record.state != TrackingState::Ok {
            continue;
        }
        let centre = pose.translation;
        if let Some((_, mapped)) = first_pass.get(record.index - offset) {
            to_map.push((centre - mapped.translation).norm());
        }
        to_truth.push((centre - truth(record.index)).norm());
    }
    let localised_fraction = to_truth.len() as f64 / records.len().max(1) as f64;
    to_map.sort_by(f64::total_cmp);
    to_truth.sort_by(f64::total_cmp);
    (to_map, to_truth, localised_fraction)
}

fn scratch() -> PathBuf {
    let dir = std::env::temp_dir().join(format!("spslam-localisation-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    ok(std::fs::create_dir_all(&dir));
    dir
}

#[test]
fn the_second_lap_localises_in_the_first_laps_saved_map() {
    let test = "the_second_lap_localises_in_the_first_laps_saved_map";
    if !common::model_available(test) {
        return;
    }
    let one_lap = small_sequence(SceneName::Loop, 1);
    let lap = (10..2000)
        .find(|&i| {
            (one_lap.pose(i).translation.vector - one_lap.pose(0).translation.vector).norm() < 1e-6
        })
        .unwrap_or_else(|| panic!("the loop scene does not return to its start"));
    let sequence = small_sequence(SceneName::Loop, 2 * lap);
    let first = sequence.pose(0).inverse();
    let truth = |i: usize| (first * sequence.pose(i)).translation.vector;

    // First pass: one lap and the return to the start (the loop closes).
    let mut mapper = system(&sequence);
    process(&mut mapper, &sequence, 0..lap + 5);
    let first_pass = ok(mapper.trajectory());
    let dir = scratch();
    let mut files = Vec::new();
    for precision in [
        DescriptorPrecision::F16,
        DescriptorPrecision::F32,
        DescriptorPrecision::U8,
    ] {
        let path = dir.join(format!("lap.{}.spmap", precision.name()));
        let saved = ok(mapper.save_map(
            &path,
            &MapProvenance::default(),
            precision,
            SaveOptions::default(),
        ));
        eprintln!(
            "first pass saved as {}: {} keyframes, {} points, {:.1} MB",
            precision.name(),
            saved.keyframes,
            saved.points,
            saved.bytes as f64 / 1e6
        );
        files.push((precision, path));
    }
    eprintln!("first pass loops: {:?}", mapper.loops().len());
    let (f16_path, f32_path, u8_path) = (&files[0].1, &files[1].1, &files[2].1);

    // Second lap, localisation only, f16 map.
    let mut localised = localiser(&sequence, f16_path);
    let before = counts(&localised);
    process(&mut localised, &sequence, lap..2 * lap);
    let (to_map, to_truth, fraction) = errors(&localised, &first_pass, truth, lap);
    let summary = ok(localised.summary());
    eprintln!(
        "second lap in the f16 map: {:.1} % of {} frames localised ({} relocalisations, {} lost), \
         error vs the first pass median {:.3} m, p95 {:.3} m; vs truth median {:.3} m, p95 {:.3} m; \
         keyframes inserted {}",
        100.0 * fraction,
        summary.frames,
        summary.relocalisations,
        summary.lost,
        percentile(&to_map, 0.5),
        percentile(&to_map, 0.95),
        percentile(&to_truth, 0.5),
        percentile(&to_truth, 0.95),
        summary.keyframes_inserted
    );
    assert!(fraction >= 0.95, "only {:.1} % localised", 100.0 * fraction);
    assert_eq!(summary.keyframes_inserted, 0);
    assert_eq!(counts(&localised), before, "the loaded map changed");
    assert!(
        percentile(&to_map, 0.5) <= 0.05,
        "median {}",
        percentile(&to_map, 0.5)
    );
    assert!(
        percentile(&to_map, 0.95) <= 0.20,
        "p95 {}",
        percentile(&to_map, 0.95)
    );

    // Kidnapped start in the middle of the map.
    let start = lap + lap / 2;
    let mut kidnapped = localiser(&sequence, f16_path);
    process(&mut kidnapped, &sequence, start..start + 10);
    let first_ok = kidnapped
        .records()
        .iter()
        .find(|r| r.state == TrackingState::Ok)
        .map(|r| r.index - start);
    eprintln!("kidnapped start at frame {start}: localised after {first_ok:?} frames");
    assert!(matches!(first_ok, Some(n) if n < 3), "{first_ok:?}");

    // The precision's effect, over the first 80 frames of the lap.
    for (precision, path) in [("f16", f16_path), ("f32", f32_path), ("u8", u8_path)] {
        let mut short = localiser(&sequence, path);
        process(&mut short, &sequence, lap..lap + 80);
        let (to_map, _, fraction) = errors(&short, &first_pass, truth, lap);
        eprintln!(
            "{precision}: {:.1} % of 80 frames localised, error vs the first pass median {:.4} m, p95 {:.4} m",
            100.0 * fraction,
            percentile(&to_map, 0.5),
            percentile(&to_map, 0.95)
        );
        assert!(
            fraction >= 0.95,
            "{precision}: only {:.1} % localised",
            100.0 * fraction
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
