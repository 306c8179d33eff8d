//! The map's bookkeeping on synthetic keyframes with known answers:
//! covisibility weights against brute-force counts, the spanning tree through
//! keyframe removal, two-sided consistency under random edit sequences,
//! fusion, culling, representative descriptors and sharing across threads.

use std::collections::BTreeSet;
use std::time::{Duration, Instant};

use nalgebra::{UnitQuaternion, Vector3};
use proptest::prelude::*;
use proptest::strategy::ValueTree;
use spslam::features::pyramid::ScaleTables;
use spslam::features::{DescriptorRef, DescriptorSet, Keypoint};
use spslam::map::{
    most_representative, FrameMeasurements, KeyFrameId, Map, MapError, MapPointId, PointDescriptor,
    StereoMeasurement,
};
use spslam::optim::{LieGroup, Se3};

const DIM: usize = 4;

fn keypoint(i: usize, octave: i32) -> Keypoint {
    Keypoint {
        x: (i % 40) as f32 * 10.0,
        y: (i / 40) as f32 * 10.0,
        size: 31.0,
        angle: 0.0,
        response: 1.0,
        octave,
    }
}

/// `n` keypoints whose descriptor row i is `[i, kf, 0, 0]` scaled down.
fn measurements(n: usize, kf: usize, octave: i32, stereo: bool) -> FrameMeasurements {
    let mut data = Vec::with_capacity(n * DIM);
    for i in 0..n {
        data.extend_from_slice(&[i as f32 * 0.01, kf as f32 * 0.001, 0.0, 0.0]);
    }
    FrameMeasurements {
        keypoints: (0..n).map(|i| keypoint(i, octave)).collect(),
        descriptors: DescriptorSet::Float { dim: DIM, data },
        stereo: (0..n)
            .map(|_| {
                stereo.then_some(StereoMeasurement {
                    right_u: 0.0,
                    depth: 5.0,
                })
            })
            .collect(),
        scales: ScaleTables::new(1000, 1.2, 8),
        distance_thresholds: spslam::features::DistanceThresholds::SUPERPOINT_L2,
    }
}

fn pose(x: f64) -> Se3 {
    Se3::new(UnitQuaternion::identity(), Vector3::new(-x, 0.0, 0.0))
}

fn descriptor() -> PointDescriptor {
    PointDescriptor::Float(vec![0.0; DIM].into())
}

/// A chain of keyframes: keyframe k creates `points_per_kf / (overlap + 1)`
/// points, each seen by keyframes k..=k+overlap at their next free keypoint.
fn chain_map(keyframes: usize, points_per_kf: usize, overlap: usize) -> (Map, Vec<KeyFrameId>) {
    let mut map = Map::new();
    let ids: Vec<KeyFrameId> = (0..keyframes)
        .map(|k| {
            map.add_keyframe(
                k,
                k as f64,
                pose(k as f64),
                measurements(points_per_kf, k, 0, false),
            )
            .expect("add keyframe")
        })
        .collect();
    let mut next_free = vec![0usize; keyframes];
    for k in 0..keyframes {
        for _ in 0..points_per_kf / (overlap + 1) {
            let p = map
                .add_map_point(Vector3::new(k as f64, 0.0, 5.0), descriptor(), ids[k])
                .expect("add point");
            for o in k..(k + overlap + 1).min(keyframes) {
                map.add_observation(p, ids[o], next_free[o])
                    .expect("observe");
                next_free[o] += 1;
            }
        }
        map.update_connections(ids[k]);
    }
    for id in &ids {
        map.update_connections(*id);
    }
    (map, ids)
}

fn brute_force_shared(map: &Map, a: KeyFrameId, b: KeyFrameId) -> usize {
    let pa: BTreeSet<MapPointId> = map
        .keyframe(a)
        .expect("a")
        .observed_points()
        .map(|(_, p)| p)
        .collect();
    let pb: BTreeSet<MapPointId> = map
        .keyframe(b)
        .expect("b")
        .observed_points()
        .map(|(_, p)| p)
        .collect();
    pa.intersection(&pb).count()
}

#[test]
fn covisibility_weights_equal_brute_force_counts() {
    let (map, ids) = chain_map(6, 60, 2);
    map.check_invariants().unwrap_or_else(|e| panic!("{e}"));
    for &a in &ids {
        for &b in &ids {
            if a != b {
                assert_eq!(
                    map.covisibility_weight(a, b),
                    brute_force_shared(&map, a, b),
                    "{a} {b}"
                );
            }
        }
        let best = map.best_covisible(a, usize::MAX);
        let weights: Vec<usize> = best
            .iter()
            .map(|b| map.covisibility_weight(a, *b))
            .collect();
        assert!(
            weights.windows(2).all(|w| w[0] >= w[1]),
            "ordered by weight: {weights:?}"
        );
        assert!(
            weights.iter().all(|w| *w >= 15),
            "only ≥ 15 shared points: {weights:?}"
        );
    }
    // Keyframes two apart share the points seen across three consecutive ones.
    assert!(map.best_covisible(ids[2], usize::MAX).contains(&ids[0]));
    assert!(!map.best_covisible(ids[3], usize::MAX).contains(&ids[0]));
}

#[test]
fn spanning_tree_survives_keyframe_removal() {
    let (mut map, ids) = chain_map(8, 60, 2);
    assert_eq!(map.parent(ids[0]), None, "the first keyframe is the root");
    for id in &ids[1..] {
        assert!(map.parent(*id).is_some(), "{id} has a parent");
    }
    let pose_before = map.keyframe(ids[3]).expect("kf").pose_cw();
    map.erase_keyframe(ids[3]).expect("erase");
    assert!(map.keyframe(ids[3]).is_err());
    map.check_invariants().unwrap_or_else(|e| panic!("{e}"));
    // Every live keyframe still reaches the root, without cycles.
    for kf in map.keyframes() {
        let mut current = kf.id();
        let mut steps = 0;
        while let Some(parent) = map.parent(current) {
            assert!(map.keyframe(parent).is_ok(), "{parent} is live");
            current = parent;
            steps += 1;
            assert!(steps <= ids.len(), "cycle from {}", kf.id());
        }
        assert_eq!(current, ids[0]);
    }
    // The culled keyframe's pose is still recoverable through its parent.
    let recovered = map.pose_cw_of(ids[3]).expect("culled pose");
    assert!((recovered.to_matrix() - pose_before.to_matrix()).amax() < 1e-12);
    // The first keyframe is never erased.
    map.erase_keyframe(ids[0]).expect("no-op");
    assert!(map.keyframe(ids[0]).is_ok());
}

/// `n` keyframes at x = 0, 1, …, each with 200 keypoints, none connected.
fn bare_keyframes(map: &mut Map, n: usize) -> Vec<KeyFrameId> {
    (0..n)
        .map(|k| {
            map.add_keyframe(k, k as f64, pose(k as f64), measurements(200, k, 0, false))
                .expect("add keyframe")
        })
        .collect()
}

/// `n` points, each seen by every keyframe in `observers` (indices into
/// `kfs`) at its next free keypoint.
fn shared_points(
    map: &mut Map,
    kfs: &[KeyFrameId],
    observers: &[usize],
    n: usize,
    next_free: &mut [usize],
) {
    for _ in 0..n {
        let p = map
            .add_map_point(Vector3::new(0.0, 0.0, 5.0), descriptor(), kfs[observers[0]])
            .expect("add point");
        for &o in observers {
            map.add_observation(p, kfs[o], next_free[o])
                .expect("observe");
            next_free[o] += 1;
        }
    }
}

/// Walks up the spanning tree from every live keyframe: each reaches `root`
/// through live parents that list it as a child, within a bounded number of
/// steps (no cycle).
fn assert_tree_reaches(map: &Map, root: KeyFrameId) {
    assert_eq!(map.parent(root), None, "the root has no parent");
    for kf in map.keyframes() {
        let mut current = kf.id();
        let mut steps = 0;
        while current != root {
            let parent = map
                .parent(current)
                .unwrap_or_else(|| panic!("{current} (above {}) has no parent", kf.id()));
            assert!(map.keyframe(parent).is_ok(), "{parent} is live");
            assert!(
                map.children(parent).contains(&current),
                "{parent} lists {current}"
            );
            current = parent;
            steps += 1;
            assert!(steps <= map.keyframe_count(), "cycle above {}", kf.id());
        }
    }
}

/// The pose of every keyframe ever added (live or culled) is recoverable and
/// still the one `bare_keyframes` gave it.
fn assert_all_poses_recoverable(map: &Map, kfs: &[KeyFrameId]) {
    for (k, &kf) in kfs.iter().enumerate() {
        let recovered = map
            .pose_cw_of(kf)
            .unwrap_or_else(|e| panic!("pose of {kf}: {e}"));
        assert!(
            (recovered.to_matrix() - pose(k as f64).to_matrix()).amax() < 1e-12,
            "pose of {kf}"
        );
    }
}

/// Regression: keyframe 1 shares no point with the root, so it used to get
/// no parent; after erasing 2 (3 and 4 re-attached under 1 and 4) and then
/// 1, keyframe 4 was left without a parent, and `update_connections(4)`
/// then took its own child 3 as parent: 3 and 4 were each other's parent.
#[test]
fn a_keyframe_without_older_covisible_ones_joins_the_tree_and_no_cycle_forms() {
    let mut map = Map::new();
    let k = bare_keyframes(&mut map, 5);
    let mut next_free = vec![0; 5];
    shared_points(&mut map, &k, &[1, 2], 20, &mut next_free);
    shared_points(&mut map, &k, &[2, 3], 20, &mut next_free);
    shared_points(&mut map, &k, &[2, 4], 30, &mut next_free);
    shared_points(&mut map, &k, &[1, 4], 20, &mut next_free);
    shared_points(&mut map, &k, &[3, 4], 20, &mut next_free);
    for &kf in &k[1..] {
        map.update_connections(kf);
    }
    map.check_invariants().unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        map.parent(k[1]),
        Some(k[0]),
        "no covisible keyframe in the tree: the newest older one"
    );
    assert_eq!(map.parent(k[2]), Some(k[1]));
    assert_eq!(map.parent(k[3]), Some(k[2]));
    assert_eq!(map.parent(k[4]), Some(k[2]), "the most covisible one");
    assert_tree_reaches(&map, k[0]);

    map.erase_keyframe(k[2]).expect("erase 2");
    map.check_invariants().unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(map.parent(k[4]), Some(k[1]), "covisible with 2's parent");
    assert_eq!(
        map.parent(k[3]),
        Some(k[4]),
        "covisible with 4, re-attached first"
    );
    assert_tree_reaches(&map, k[0]);

    map.erase_keyframe(k[1]).expect("erase 1");
    map.check_invariants().unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        map.parent(k[4]),
        Some(k[0]),
        "no covisible candidate: 1's parent"
    );
    assert_eq!(map.parent(k[3]), Some(k[4]));
    assert_tree_reaches(&map, k[0]);

    for &kf in &k[3..] {
        map.update_connections(kf);
    }
    map.check_invariants().unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(map.parent(k[4]), Some(k[0]), "a parent is only set once");
    assert_eq!(map.parent(k[3]), Some(k[4]));
    assert_tree_reaches(&map, k[0]);
    assert_all_poses_recoverable(&map, &k);
}

/// Regression: a keyframe erased without a parent left no culled record,
/// so `pose_cw_of` failed for it and for the keyframes culled under it.
#[test]
fn every_erased_keyframe_keeps_a_recoverable_pose() {
    let mut map = Map::new();
    let k = bare_keyframes(&mut map, 6);
    let mut next_free = vec![0; 6];
    // 2 shares nothing with 0 or 1; 3 and 4 hang below it.
    shared_points(&mut map, &k, &[0, 1], 20, &mut next_free);
    shared_points(&mut map, &k, &[2, 3], 20, &mut next_free);
    shared_points(&mut map, &k, &[3, 4], 20, &mut next_free);
    shared_points(&mut map, &k, &[2, 4], 20, &mut next_free);
    for &kf in &k[1..5] {
        map.update_connections(kf);
    }
    // Keyframe 5 is never connected: it is not in the tree yet.
    map.check_invariants().unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(map.parent(k[2]), Some(k[1]), "the newest older keyframe");
    assert_eq!(map.parent(k[3]), Some(k[2]));
    assert_eq!(map.parent(k[5]), None, "not connected yet");

    map.erase_keyframe(k[3]).expect("erase 3");
    map.check_invariants().unwrap_or_else(|e| panic!("{e}"));
    map.erase_keyframe(k[2]).expect("erase 2");
    map.check_invariants().unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        map.parent(k[4]),
        Some(k[1]),
        "no covisible candidate: 2's parent"
    );
    map.erase_keyframe(k[5]).expect("erase the unconnected 5");
    map.check_invariants().unwrap_or_else(|e| panic!("{e}"));
    map.erase_keyframe(k[1]).expect("erase 1");
    map.check_invariants().unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(map.parent(k[4]), Some(k[0]));
    assert_tree_reaches(&map, k[0]);
    assert_all_poses_recoverable(&map, &k);
    assert!(
        map.pose_cw_of(KeyFrameId(6)).is_err(),
        "never a keyframe of this map"
    );
}

#[test]
fn points_left_with_two_observations_are_erased_and_stereo_counts_twice() {
    let mut map = Map::new();
    let a = map
        .add_keyframe(0, 0.0, pose(0.0), measurements(5, 0, 0, false))
        .expect("a");
    let b = map
        .add_keyframe(1, 1.0, pose(1.0), measurements(5, 1, 0, false))
        .expect("b");
    let c = map
        .add_keyframe(2, 2.0, pose(2.0), measurements(5, 2, 0, true))
        .expect("c");
    let p = map
        .add_map_point(Vector3::new(0.0, 0.0, 5.0), descriptor(), a)
        .expect("p");
    map.add_observation(p, a, 0).expect("a");
    map.add_observation(p, b, 1).expect("b");
    map.add_observation(p, c, 2).expect("c");
    assert_eq!(
        map.map_point(p).expect("p").observation_count(),
        4,
        "stereo counts twice"
    );
    map.erase_observation(p, c).expect("erase c");
    assert!(map.map_point(p).is_err(), "two observations left: erased");
    assert_eq!(map.keyframe(a).expect("a").map_point(0), None);
    map.check_invariants().unwrap_or_else(|e| panic!("{e}"));
}

#[test]
fn bad_ids_and_indices_are_typed_errors() {
    let mut map = Map::new();
    let a = map
        .add_keyframe(0, 0.0, pose(0.0), measurements(3, 0, 0, false))
        .expect("a");
    let p = map
        .add_map_point(Vector3::zeros(), descriptor(), a)
        .expect("p");
    let q = map
        .add_map_point(Vector3::zeros(), descriptor(), a)
        .expect("q");
    assert_eq!(
        map.add_observation(p, a, 3),
        Err(MapError::KeypointOutOfRange {
            keyframe: a,
            index: 3,
            keypoints: 3
        })
    );
    assert_eq!(
        map.add_observation(p, KeyFrameId(9), 0),
        Err(MapError::UnknownKeyFrame(KeyFrameId(9)))
    );
    map.add_observation(p, a, 0).expect("first");
    assert_eq!(
        map.add_observation(q, a, 0),
        Err(MapError::KeypointTaken {
            keyframe: a,
            index: 0,
            existing: p
        })
    );
    let mut bad = measurements(3, 0, 0, false);
    bad.stereo.pop();
    assert!(matches!(
        map.add_keyframe(1, 1.0, pose(1.0), bad),
        Err(MapError::InconsistentKeyFrame {
            keypoints: 3,
            stereo: 2,
            ..
        })
    ));
}

#[test]
fn fusion_merges_observations_and_redirects_the_old_id() {
    let mut map = Map::new();
    let kfs: Vec<KeyFrameId> = (0..4)
        .map(|k| {
            map.add_keyframe(k, k as f64, pose(k as f64), measurements(6, k, 0, false))
                .expect("kf")
        })
        .collect();
    let old = map
        .add_map_point(Vector3::new(0.0, 0.0, 4.0), descriptor(), kfs[0])
        .expect("old");
    let new = map
        .add_map_point(Vector3::new(0.0, 0.0, 4.0), descriptor(), kfs[1])
        .expect("new");
    map.add_observation(old, kfs[0], 0).expect("o0");
    map.add_observation(old, kfs[1], 1).expect("o1");
    map.add_observation(new, kfs[1], 2).expect("n1");
    map.add_observation(new, kfs[2], 3).expect("n2");
    map.add_observation(new, kfs[3], 4).expect("n3");
    map.replace_map_point(old, new).expect("fuse");
    let merged = map.map_point(new).expect("new");
    let observers: Vec<KeyFrameId> = merged.observations().keys().copied().collect();
    assert_eq!(
        observers, kfs,
        "kf1 keeps its own keypoint for the new point"
    );
    assert_eq!(map.keyframe(kfs[1]).expect("kf1").map_point(1), None);
    assert_eq!(map.resolve_point(old), Some(new));
    assert_eq!(merged.visible, 2);
    map.check_invariants().unwrap_or_else(|e| panic!("{e}"));
}

#[test]
fn representative_descriptor_is_the_least_median_one() {
    // On a line at 0, 1.5, 2, 2.5, 4: the point at 2 has median distance 0.5,
    // the others 1 or more.
    let rows: Vec<Vec<f32>> = [0.0, 1.5, 2.0, 2.5, 4.0]
        .iter()
        .map(|x| vec![*x, 0.0])
        .collect();
    let refs: Vec<DescriptorRef<'_>> = rows.iter().map(|r| DescriptorRef::Float(r)).collect();
    assert_eq!(
        most_representative(&refs),
        Some(2),
        "the middle of the cluster"
    );
    assert_eq!(most_representative(&[]), None);
    // Bytes with 0, 3, 4, 5 and 8 bits set: on a line at 0, 3, 4, 5, 8 (×32 bits).
    let bits = [[0x00u8; 32], [0x07; 32], [0x0F; 32], [0x1F; 32], [0xFF; 32]];
    let refs: Vec<DescriptorRef<'_>> = bits.iter().map(DescriptorRef::Binary).collect();
    assert_eq!(
        most_representative(&refs),
        Some(2),
        "Hamming: the middle one"
    );
}

#[test]
fn normal_points_from_the_cameras_and_distances_follow_the_octave() {
    let mut map = Map::new();
    let a = map
        .add_keyframe(0, 0.0, pose(-1.0), measurements(2, 0, 2, false))
        .expect("a");
    let b = map
        .add_keyframe(1, 1.0, pose(1.0), measurements(2, 1, 2, false))
        .expect("b");
    let p = map
        .add_map_point(Vector3::new(0.0, 0.0, 10.0), descriptor(), a)
        .expect("p");
    map.add_observation(p, a, 0).expect("a");
    map.add_observation(p, b, 0).expect("b");
    map.update_normal_and_depth(p);
    let point = map.map_point(p).expect("p");
    assert!(
        (point.normal - Vector3::z()).norm() < 1e-12,
        "symmetric views: normal along z"
    );
    let distance = 101f64.sqrt();
    let scale2 = f64::from(1.2f32 * 1.2f32);
    assert!((point.max_distance - distance * scale2).abs() < 1e-5);
    assert!((point.min_distance - point.max_distance / f64::from(1.2f32.powi(7))).abs() < 1e-5);
    assert_eq!(
        point.predict_octave(distance, 1.2, 8),
        2,
        "seen from where it was made: its octave"
    );
}

#[test]
fn recent_points_culling_follows_orb_slam3() {
    let mut map = Map::new();
    let kfs: Vec<KeyFrameId> = (0..4)
        .map(|k| {
            map.add_keyframe(k, k as f64, pose(k as f64), measurements(4, k, 0, false))
                .expect("kf")
        })
        .collect();
    let weak = map
        .add_map_point(Vector3::zeros(), descriptor(), kfs[0])
        .expect("weak");
    let lonely = map
        .add_map_point(Vector3::zeros(), descriptor(), kfs[0])
        .expect("lonely");
    let good = map
        .add_map_point(Vector3::zeros(), descriptor(), kfs[0])
        .expect("good");
    let young = map
        .add_map_point(Vector3::zeros(), descriptor(), kfs[2])
        .expect("young");
    for (p, n) in [(weak, 3), (lonely, 2), (good, 4), (young, 1)] {
        for (j, kf) in kfs.iter().take(n).enumerate() {
            let index = [weak, lonely, good, young]
                .iter()
                .position(|x| *x == p)
                .unwrap_or(0);
            let _ = j;
            map.add_observation(p, *kf, index).expect("observe");
        }
    }
    map.map_point_mut(weak).expect("weak").visible.set(10); // found 1 of 10
    let mut recent = vec![weak, lonely, good, young];
    let report = map.cull_recent_points(&mut recent, kfs[3], 2);
    assert_eq!(report.low_found_ratio, 1);
    assert_eq!(report.too_few_observations, 1);
    assert_eq!(report.confirmed, 1);
    assert_eq!(recent, vec![young]);
    assert!(map.map_point(weak).is_err() && map.map_point(lonely).is_err());
    assert!(map.map_point(good).is_ok());
}

#[test]
fn a_keyframe_whose_points_others_see_is_redundant() {
    // Five keyframes all seeing the same 30 points: every one but the first is redundant.
    let mut map = Map::new();
    let kfs: Vec<KeyFrameId> = (0..5)
        .map(|k| {
            map.add_keyframe(k, k as f64, pose(k as f64), measurements(30, k, 0, true))
                .expect("kf")
        })
        .collect();
    for j in 0..30 {
        let p = map
            .add_map_point(Vector3::new(0.0, 0.0, 5.0), descriptor(), kfs[0])
            .expect("p");
        for kf in &kfs {
            map.add_observation(p, *kf, j).expect("observe");
        }
    }
    assert_eq!(map.redundant_keyframes(&kfs, Some(20.0)), kfs[1..].to_vec());
    assert!(
        map.redundant_keyframes(&kfs, Some(1.0)).is_empty(),
        "no close points: nothing counted"
    );
}

#[test]
fn tracking_and_mapping_threads_share_the_map() {
    let shared = Map::new().into_shared();
    let writer = {
        let shared = shared.clone();
        std::thread::spawn(move || {
            for k in 0..50 {
                let mut map = shared.write().expect("lock");
                let kf = map
                    .add_keyframe(k, k as f64, pose(k as f64), measurements(20, k, 0, false))
                    .expect("kf");
                for j in 0..20 {
                    let p = map
                        .add_map_point(Vector3::zeros(), descriptor(), kf)
                        .expect("p");
                    map.add_observation(p, kf, j).expect("obs");
                }
            }
        })
    };
    // The reader fails instead of spinning when the writer dies early (its
    // panic is re-raised here) or the 50 keyframes take implausibly long.
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        // Sampled before reading, so a writer that is done has finished writing.
        let writer_done = writer.is_finished();
        let seen = match shared.read() {
            Ok(map) => {
                map.check_invariants().unwrap_or_else(|e| panic!("{e}"));
                assert_eq!(map.map_point_count(), 20 * map.keyframe_count());
                map.keyframe_count()
            }
            // Poisoned: the writer panicked while holding the lock.
            Err(_) => join_writer(writer, "poisoned the map lock"),
        };
        if seen >= 50 {
            break;
        }
        if writer_done {
            join_writer(writer, &format!("stopped after {seen} keyframes"));
        }
        assert!(
            Instant::now() < deadline,
            "the reader saw only {seen} of 50 keyframes within 60 s"
        );
        std::thread::yield_now();
    }
    writer.join().expect("writer thread");
}

/// Joins a writer thread that ended early and fails the test with its panic
/// message (or with `what` when it returned normally).
fn join_writer(writer: std::thread::JoinHandle<()>, what: &str) -> ! {
    match writer.join() {
        Ok(()) => panic!("the writer thread {what} without panicking"),
        Err(payload) => {
            let message = payload
                .downcast_ref::<&str>()
                .copied()
                .or_else(|| payload.downcast_ref::<String>().map(String::as_str))
                .unwrap_or("(non-string panic payload)");
            panic!("the writer thread {what}: it panicked with: {message}")
        }
    }
}

/// Random edit sequences keep both sides of every association consistent.
#[derive(Debug, Clone)]
enum Edit {
    Observe {
        point: usize,
        kf: usize,
        index: usize,
    },
    Unobserve {
        point: usize,
        kf: usize,
    },
    Fuse {
        old: usize,
        new: usize,
    },
    EraseKeyFrame {
        kf: usize,
    },
    /// `update_connections` on one keyframe: keyframes join the spanning
    /// tree in random order, some never, some after their neighbours.
    Connect {
        kf: usize,
    },
    /// `update_connections` on every live keyframe, in id order.
    ConnectAll,
}

const EDIT_KEYFRAMES: usize = 6;

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        4 => (0..12usize, 0..EDIT_KEYFRAMES, 0..8usize).prop_map(|(point, kf, index)| Edit::Observe { point, kf, index }),
        2 => (0..12usize, 0..EDIT_KEYFRAMES).prop_map(|(point, kf)| Edit::Unobserve { point, kf }),
        1 => (0..12usize, 0..12usize).prop_map(|(old, new)| Edit::Fuse { old, new }),
        2 => (0..EDIT_KEYFRAMES).prop_map(|kf| Edit::EraseKeyFrame { kf }),
        2 => (0..EDIT_KEYFRAMES).prop_map(|kf| Edit::Connect { kf }),
        1 => Just(Edit::ConnectAll),
    ]
}

fn edits() -> impl Strategy<Value = Vec<Edit>> {
    proptest::collection::vec(edit(), 1..60)
}

/// What the keyframes erased in one edit sequence were like when erased.
#[derive(Debug, Default)]
struct Erasures {
    /// Sharing a point with another live keyframe.
    covisible: usize,
    /// Sharing no point with any other live keyframe.
    isolated: usize,
    /// With spanning-tree children to re-attach.
    with_children: usize,
    /// Never connected (not in the spanning tree yet).
    unconnected: usize,
}

/// Applies `edits` to a fresh map, checking after each one its invariants,
/// that every keyframe ever added still has its pose, and, after
/// `ConnectAll`, that the covisibility weights are the exact counts.
fn run_edits(edits: &[Edit]) -> Result<Erasures, TestCaseError> {
    let mut map = Map::new();
    let kfs: Vec<KeyFrameId> = (0..EDIT_KEYFRAMES)
        .map(|k| {
            map.add_keyframe(
                k,
                k as f64,
                pose(k as f64),
                measurements(8, k, 0, k % 2 == 0),
            )
            .expect("kf")
        })
        .collect();
    let points: Vec<MapPointId> = (0..12)
        .map(|_| {
            map.add_map_point(Vector3::zeros(), descriptor(), kfs[0])
                .expect("p")
        })
        .collect();
    let mut connected = BTreeSet::new();
    let mut erasures = Erasures::default();
    for e in edits {
        // Errors (taken slots, dead ids) are expected; panics and inconsistency are not.
        let _ = match *e {
            Edit::Observe { point, kf, index } => {
                map.add_observation(points[point], kfs[kf], index)
            }
            Edit::Unobserve { point, kf } => map.erase_observation(points[point], kfs[kf]),
            Edit::Fuse { old, new } => map.replace_map_point(points[old], points[new]),
            Edit::EraseKeyFrame { kf } => {
                let id = kfs[kf];
                if kf != 0 && map.keyframe(id).is_ok() {
                    let covisible = map.keyframes().any(|other| {
                        other.id() != id && brute_force_shared(&map, id, other.id()) > 0
                    });
                    if covisible {
                        erasures.covisible += 1;
                    } else {
                        erasures.isolated += 1;
                    }
                    if !map.children(id).is_empty() {
                        erasures.with_children += 1;
                    }
                    if !connected.contains(&id) {
                        erasures.unconnected += 1;
                    }
                }
                map.erase_keyframe(id)
            }
            Edit::Connect { kf } => {
                map.update_connections(kfs[kf]);
                if map.keyframe(kfs[kf]).is_ok() {
                    connected.insert(kfs[kf]);
                }
                Ok(())
            }
            Edit::ConnectAll => {
                let live: Vec<KeyFrameId> = map.keyframes().map(|k| k.id()).collect();
                for kf in &live {
                    map.update_connections(*kf);
                }
                connected.extend(live);
                Ok(())
            }
        };
        prop_assert_eq!(map.check_invariants(), Ok(()), "after {:?}", e);
        for kf in map.keyframes() {
            let id = kf.id();
            if id != kfs[0] {
                prop_assert_eq!(
                    map.parent(id).is_some(),
                    connected.contains(&id),
                    "{} has a parent once connected",
                    id
                );
            }
        }
        for (k, &kf) in kfs.iter().enumerate() {
            let recovered = map.pose_cw_of(kf);
            prop_assert!(recovered.is_ok(), "pose of {} after {:?}", kf, e);
            let error = recovered.map_or(f64::INFINITY, |p| {
                (p.to_matrix() - pose(k as f64).to_matrix()).amax()
            });
            prop_assert!(
                error < 1e-12,
                "pose of {} off by {} after {:?}",
                kf,
                error,
                e
            );
        }
        if matches!(e, Edit::ConnectAll) {
            // With every keyframe's connections just recomputed, the weights
            // are the exact shared-point counts, and so symmetric (between
            // updates they may be stale: see `Map::check_invariants`).
            let live: Vec<KeyFrameId> = map.keyframes().map(|k| k.id()).collect();
            for &a in &live {
                for &b in &live {
                    if a != b {
                        prop_assert_eq!(
                            map.covisibility_weight(a, b),
                            brute_force_shared(&map, a, b)
                        );
                    }
                }
            }
        }
    }
    Ok(erasures)
}

proptest! {
    #[test]
    fn random_edits_keep_the_map_consistent(edits in edits()) {
        run_edits(&edits)?;
    }
}

/// The random edits erase keyframes of every kind: sharing points with
/// others or none, with children to re-attach, and never connected.
#[test]
fn random_edits_erase_keyframes_with_and_without_covisible_ones() {
    let mut runner = proptest::test_runner::TestRunner::deterministic();
    let mut total = Erasures::default();
    for _ in 0..256 {
        let sequence = edits().new_tree(&mut runner).expect("sample").current();
        let e = run_edits(&sequence).unwrap_or_else(|e| panic!("{e}: {sequence:?}"));
        total.covisible += e.covisible;
        total.isolated += e.isolated;
        total.with_children += e.with_children;
        total.unconnected += e.unconnected;
    }
    println!("{total:?}");
    assert!(total.covisible >= 20, "{total:?}");
    assert!(total.isolated >= 20, "{total:?}");
    assert!(total.with_children >= 20, "{total:?}");
    assert!(total.unconnected >= 20, "{total:?}");
}
