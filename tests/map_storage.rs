//! Map storage on real maps (stereo SLAM over a synthetic street):
//!
//! - a round trip reproduces the map exactly: the parts (poses, points,
//!   observations, graphs, counters) equal, descriptors bit-exact in f32,
//!   within their precision's bound in f16 and u8;
//! - a map loaded and saved again (ORB-SLAM3's "second save crashes")
//!   reloads equal;
//! - an interrupted save leaves the previous file loadable;
//! - a file of another format version, a truncated file and a file with
//!   a flipped bit are typed errors naming the fault;
//! - a map loaded to continue mapping grows, stays consistent, and saves
//!   and loads again; a file made with another model or extractor is
//!   refused, naming both;
//! - file size per keyframe for f32, f16 and u8 (printed, `--nocapture`).

mod common;

use std::path::PathBuf;

use spslam::features::DescriptorSet;
use spslam::map::MapParts;
use spslam::storage::{load, DescriptorPrecision, SaveOptions, StorageError};
use spslam::system::{MapProvenance, SlamSystem};

fn ok<T, E: std::fmt::Display>(r: Result<T, E>) -> T {
    r.unwrap_or_else(|e| panic!("{e}"))
}

/// A fresh directory under the target dir.
fn scratch(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("spslam-map-storage-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    ok(std::fs::create_dir_all(&dir));
    dir
}

fn provenance() -> MapProvenance {
    MapProvenance {
        extractor_settings: "test".into(),
        model_hash: Some("0123456789abcdef".into()),
        codebook_hash: None,
    }
}

/// Every map's parts, descriptors included.
fn parts_of(slam: &SlamSystem) -> Vec<MapParts> {
    slam.atlas()
        .maps()
        .iter()
        .map(|m| ok(m.map.read().map_err(|_| "poisoned")).to_parts())
        .collect()
}

/// Parts with the descriptors emptied, for comparisons that leave them out.
fn without_descriptors(mut parts: MapParts) -> MapParts {
    for kf in &mut parts.keyframes {
        kf.descriptors = DescriptorSet::Float {
            dim: 0,
            data: Vec::new(),
        };
    }
    for p in &mut parts.points {
        p.descriptor = spslam::map::PointDescriptor::Float(Vec::new().into());
    }
    parts
}

fn float_rows(parts: &MapParts) -> Vec<f32> {
    let mut out = Vec::new();
    for kf in &parts.keyframes {
        if let DescriptorSet::Float { data, .. } = &kf.descriptors {
            out.extend_from_slice(data);
        }
    }
    for p in &parts.points {
        if let spslam::map::PointDescriptor::Float(v) = &p.descriptor {
            out.extend_from_slice(v);
        }
    }
    out
}

#[test]
fn orb_map_round_trips_exactly_and_survives_a_second_save() {
    let slam = common::map_files::orb_system(40);
    let dir = scratch("orb");
    let path = dir.join("orb.spmap");
    let report = ok(slam.save_map(
        &path,
        &provenance(),
        DescriptorPrecision::F16,
        SaveOptions::default(),
    ));
    assert!(report.keyframes > 3, "{report:?}");
    let loaded = ok(load(&path));
    assert_eq!(loaded.maps.len(), slam.atlas().maps().len());
    assert_eq!(loaded.meta.model_hash.as_deref(), Some("0123456789abcdef"));
    let original = parts_of(&slam);
    let back: Vec<MapParts> = loaded.maps.iter().map(|m| m.map.to_parts()).collect();
    // Binary descriptors are stored as they are, whatever the precision.
    assert_eq!(back, original);
    // Save the loaded map again and reload it.
    let again = dir.join("again.spmap");
    let maps: Vec<_> = loaded
        .maps
        .iter()
        .map(|m| spslam::storage::MapToSave {
            index: m.index,
            first_frame: m.first_frame,
            merged_into: m.merged_into,
            map: &m.map,
        })
        .collect();
    ok(spslam::storage::save(
        &again,
        &loaded.meta,
        &maps,
        SaveOptions::default(),
    ));
    let reloaded = ok(load(&again));
    let back2: Vec<MapParts> = reloaded.maps.iter().map(|m| m.map.to_parts()).collect();
    assert_eq!(back2, original);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn an_interrupted_save_leaves_the_previous_file_and_bad_files_are_named() {
    let slam = common::map_files::orb_system(20);
    let dir = scratch("interrupt");
    let path = dir.join("map.spmap");
    ok(slam.save_map(
        &path,
        &provenance(),
        DescriptorPrecision::F16,
        SaveOptions::default(),
    ));
    let before = ok(std::fs::read(&path));
    for cut in [0, 10, 1000, before.len() / 2] {
        let r = slam.save_map(
            &path,
            &provenance(),
            DescriptorPrecision::F32,
            SaveOptions {
                interrupt_after: Some(cut),
            },
        );
        assert!(
            matches!(
                r,
                Err(spslam::error::SlamError::Storage(
                    StorageError::Interrupted { .. }
                ))
            ),
            "{r:?}"
        );
        assert_eq!(
            ok(std::fs::read(&path)),
            before,
            "the previous file changed"
        );
        assert!(load(&path).is_ok());
    }
    // Another version, a truncation, a flipped bit, not a map at all.
    let write = |name: &str, bytes: &[u8]| {
        let p = dir.join(name);
        ok(std::fs::write(&p, bytes));
        p
    };
    // Version 1 (before the sensor was stored), version 2 (before the
    // descriptor-distance thresholds were) and a future version 4.
    for version in [1u8, 2, 4] {
        let mut other = before.clone();
        other[8] = version;
        let name = format!("v{version}.spmap");
        let e = load(&write(&name, &other))
            .map(|_| ())
            .map_err(|e| e.to_string());
        assert!(
            matches!(&e, Err(m) if m.contains(&format!("version {version}")) && m.contains(&name)),
            "{e:?}"
        );
    }
    let e = load(&write("cut.spmap", &before[..before.len() - 7]));
    assert!(matches!(e, Err(StorageError::Truncated { .. })), "{e:?}");
    let mut flipped = before.clone();
    let at = flipped.len() / 3;
    flipped[at] ^= 0x10;
    let e = load(&write("flip.spmap", &flipped));
    assert!(
        matches!(e, Err(StorageError::ChecksumMismatch { .. })),
        "{e:?}"
    );
    let e = load(&write("text.spmap", b"hello, not a map"));
    assert!(matches!(e, Err(StorageError::NotAMapFile { .. })), "{e:?}");
    let e = load(&dir.join("missing.spmap"));
    assert!(matches!(e, Err(StorageError::Io { .. })), "{e:?}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn superpoint_map_round_trips_in_every_precision() {
    if !common::model_available("superpoint_map_round_trips_in_every_precision") {
        return;
    }
    let slam = common::map_files::superpoint_system(30, 1000);
    let dir = scratch("superpoint");
    let original = parts_of(&slam);
    let rows = float_rows(&original[0]);
    assert!(!rows.is_empty(), "no float descriptors");
    for (precision, bound) in [
        (DescriptorPrecision::F32, 0.0f32),
        (DescriptorPrecision::F16, 1.0 / 2048.0),
        (DescriptorPrecision::U8, 1.0 / 254.0 + 1e-6),
    ] {
        let path = dir.join(format!("{}.spmap", precision.name()));
        let report = ok(slam.save_map(&path, &provenance(), precision, SaveOptions::default()));
        let loaded = ok(load(&path));
        let back: Vec<MapParts> = loaded.maps.iter().map(|m| m.map.to_parts()).collect();
        let features: usize = original[0]
            .keyframes
            .iter()
            .map(|k| k.keypoints.len())
            .sum::<usize>()
            / original[0].keyframes.len().max(1);
        eprintln!(
            "{}: {} bytes, {} keyframes ({} keypoints each on average), {} points: {:.3} MB per keyframe",
            precision.name(),
            report.bytes,
            report.keyframes,
            features,
            report.points,
            report.bytes as f64 / report.keyframes as f64 / 1e6
        );
        if precision == DescriptorPrecision::F32 {
            assert_eq!(back, original, "f32 is not bit-exact");
            continue;
        }
        let stripped: Vec<MapParts> = back.into_iter().map(without_descriptors).collect();
        let expected: Vec<MapParts> = original.iter().cloned().map(without_descriptors).collect();
        assert_eq!(
            stripped, expected,
            "{precision:?} changed more than descriptors"
        );
        let got = float_rows(&loaded.maps[0].map.to_parts());
        assert_eq!(got.len(), rows.len());
        // SuperPoint rows are unit vectors: |value| ≤ 1, so the f16 error
        // is at most half an ulp of 1 and the u8 error half a step.
        let worst = got
            .iter()
            .zip(&rows)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        eprintln!(
            "{}: largest descriptor value error {worst:.2e}",
            precision.name()
        );
        assert!(worst <= bound, "{precision:?}: {worst}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_loaded_map_keeps_growing_and_a_foreign_one_is_refused() {
    let sequence =
        common::synthetic_slam::small_sequence(spslam::dataset::synthetic::SceneName::Loop, 40);
    let mut first = common::synthetic_slam::orb_slam(&sequence);
    for i in 0..30 {
        let (t, l, r) = common::synthetic_slam::images(&sequence, i);
        ok(first.process(i, t, l.view(), r.view()));
    }
    ok(first.finish());
    let dir = scratch("continue");
    let path = dir.join("first.spmap");
    ok(first.save_map(
        &path,
        &provenance(),
        DescriptorPrecision::F16,
        SaveOptions::default(),
    ));
    let keyframes_before: usize = ok(load(&path))
        .maps
        .iter()
        .map(|m| m.map.keyframe_count())
        .sum();

    // Another model: refused, both fingerprints named, nothing changed.
    let mut other = common::synthetic_slam::orb_slam(&sequence);
    let foreign = MapProvenance {
        model_hash: Some("fedcba9876543210".into()),
        ..provenance()
    };
    let refused = other
        .load_map(
            &path,
            ok(load(&path)),
            &foreign,
            spslam::system::LoadedMapUse::ContinueMapping,
        )
        .map_err(|e| e.to_string());
    assert!(
        matches!(&refused, Err(m) if m.contains("0123456789abcdef") && m.contains("fedcba9876543210")),
        "{refused:?}"
    );
    assert!(other.records().is_empty());

    // The same: continue mapping from frame 15, inside the map (ORB-SLAM3
    // inserts no keyframe for a second after a relocalisation, so a start
    // at the map's edge would lose the camera before it could extend it).
    let mut second = common::synthetic_slam::orb_slam(&sequence);
    ok(second.load_map(
        &path,
        ok(load(&path)),
        &provenance(),
        spslam::system::LoadedMapUse::ContinueMapping,
    ));
    for i in 15..40 {
        let (t, l, r) = common::synthetic_slam::images(&sequence, i);
        ok(second.process(i, t, l.view(), r.view()));
    }
    ok(second.finish());
    let summary = ok(second.summary());
    eprintln!(
        "continued: {} of 25 frames tracked, {} relocalisations, {} keyframes inserted, {} maps",
        summary.tracked,
        summary.relocalisations,
        summary.keyframes_inserted,
        summary.maps.len()
    );
    assert_eq!(summary.tracked, 25, "{summary:?}");
    assert!(summary.relocalisations >= 1);
    assert!(summary.keyframes_inserted > 0);
    assert_eq!(summary.maps.len(), 1, "a new map was started");
    for m in second.atlas().maps() {
        assert_eq!(
            ok(m.map.read().map_err(|_| "poisoned")).check_invariants(),
            Ok(())
        );
    }
    // Save after load (ORB-SLAM3 users' second-save crash), load again.
    let again = dir.join("second.spmap");
    ok(second.save_map(
        &again,
        &provenance(),
        DescriptorPrecision::F16,
        SaveOptions::default(),
    ));
    let reloaded: usize = ok(load(&again))
        .maps
        .iter()
        .map(|m| m.map.keyframe_count())
        .sum();
    assert!(
        reloaded > keyframes_before,
        "{reloaded} <= {keyframes_before}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
