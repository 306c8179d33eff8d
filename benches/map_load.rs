//! Loading a 500-keyframe map file (issue 16's target: ≤ 1 s): 500
//! keyframes of 1,000 keypoints with 256-float unit descriptors, 100,000
//! points each seen by 3 keyframes, the covisibility graph; saved in f32,
//! f16 and u8. `load` reads the file, checks its CRC-32, decodes it and
//! rebuilds every map with its consistency check. Before the criterion
//! groups it prints each file's size and its size per keyframe.
use criterion::{black_box, criterion_group, criterion_main, Criterion};
use nalgebra::{UnitQuaternion, Vector3};
use spslam::features::pyramid::ScaleTables;
use spslam::features::{DescriptorSet, Keypoint};
use spslam::map::{FrameMeasurements, KeyFrameId, Map, PointDescriptor, StereoMeasurement};
use spslam::optim::Se3;
use spslam::place::global_descriptor::l2_normalise;
use spslam::place::SeededRng;
use spslam::storage::{
    load, save, DescriptorPrecision, MapFileMeta, MapToSave, SaveOptions, StoredRig,
};

const KEYFRAMES: usize = 500;
const KEYPOINTS: usize = 1000;
const DIM: usize = 256;
const NEW_POINTS: usize = 200;

fn measurements(rng: &mut SeededRng) -> FrameMeasurements {
    let mut data = Vec::with_capacity(KEYPOINTS * DIM);
    for _ in 0..KEYPOINTS {
        let mut row: Vec<f32> = (0..DIM).map(|_| rng.next_unit() as f32 - 0.5).collect();
        l2_normalise(&mut row);
        data.extend(row);
    }
    FrameMeasurements {
        keypoints: (0..KEYPOINTS)
            .map(|i| Keypoint {
                x: (i % 40) as f32 * 12.0,
                y: (i / 40) as f32 * 14.0,
                size: 31.0,
                angle: 0.0,
                response: 1.0,
                octave: 0,
            })
            .collect(),
        descriptors: DescriptorSet::Float { dim: DIM, data },
        stereo: (0..KEYPOINTS)
            .map(|_| {
                Some(StereoMeasurement {
                    right_u: 10.0,
                    depth: 8.0,
                })
            })
            .collect(),
        scales: ScaleTables::new(KEYPOINTS, 1.2, 1),
        distance_thresholds: spslam::features::DistanceThresholds::SUPERPOINT_L2,
    }
}

fn build_map() -> Map {
    let mut rng = SeededRng::new(16);
    let mut map = Map::new();
    let mut keyframes: Vec<KeyFrameId> = Vec::new();
    for k in 0..KEYFRAMES {
        let pose = Se3::new(
            UnitQuaternion::identity(),
            Vector3::new(-(k as f64) * 0.5, 0.0, 0.0),
        );
        let kf = map
            .add_keyframe(k, k as f64 * 0.1, pose, measurements(&mut rng))
            .expect("keyframe");
        keyframes.push(kf);
        for i in 0..NEW_POINTS {
            let descriptor = {
                let set = &map.keyframe(kf).expect("kf").measurements.descriptors;
                PointDescriptor::from_set(set, i).expect("row")
            };
            let p = map
                .add_map_point(
                    Vector3::new(k as f64 * 0.5, i as f64 * 0.01, 8.0),
                    descriptor,
                    kf,
                )
                .expect("point");
            map.add_observation(p, kf, i).expect("observation");
            for back in 1..=2 {
                if let Some(older) = k.checked_sub(back).map(|j| keyframes[j]) {
                    map.add_observation(p, older, NEW_POINTS * back + i)
                        .expect("observation");
                }
            }
        }
        map.update_connections(kf);
    }
    map
}

fn bench(c: &mut Criterion) {
    let map = build_map();
    assert_eq!(map.check_invariants(), Ok(()));
    let dir = std::env::temp_dir().join(format!("spslam-bench-map-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch dir");
    let mut g = c.benchmark_group("map_load_500_keyframes");
    g.sample_size(10);
    for precision in [
        DescriptorPrecision::F32,
        DescriptorPrecision::F16,
        DescriptorPrecision::U8,
    ] {
        let path = dir.join(format!("map.{}.spmap", precision.name()));
        let meta = MapFileMeta {
            spslam_version: "bench".into(),
            extractor: "superpoint".into(),
            extractor_settings: String::new(),
            model_hash: None,
            codebook_hash: None,
            rig: StoredRig {
                fx: 700.0,
                fy: 700.0,
                cx: 600.0,
                cy: 180.0,
                bf: 380.0,
                baseline: 0.54,
                width: 1241,
                height: 376,
                close_depth: 20.0,
                max_depth: None,
                fps: 10.0,
                sensor: spslam::camera::Sensor::Stereo,
            },
            precision,
            active_map: 0,
        };
        let maps = [MapToSave {
            index: 0,
            first_frame: 0,
            merged_into: None,
            map: &map,
        }];
        let started = std::time::Instant::now();
        let report = save(&path, &meta, &maps, SaveOptions::default()).expect("save");
        println!(
            "{}: {} bytes, {:.3} MB per keyframe, saved in {:.0} ms",
            precision.name(),
            report.bytes,
            report.bytes as f64 / KEYFRAMES as f64 / 1e6,
            started.elapsed().as_secs_f64() * 1e3
        );
        g.bench_function(precision.name(), |b| {
            b.iter(|| load(black_box(&path)).expect("load").maps.len())
        });
    }
    g.finish();
    let _ = std::fs::remove_dir_all(&dir);
}

criterion_group!(benches, bench);
criterion_main!(benches);
