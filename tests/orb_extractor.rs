//! The ORB baseline extractor on a KITTI frame: count, spread over the image,
//! octaves against the per-level quotas, determinism and descriptor shape.

mod common;

use spslam::features::{DescriptorSet, FeatureExtractor, OrbConfig, OrbExtractor};

#[test]
fn orb_on_kitti_has_orb_slam3_distribution() {
    let Some(data) = common::data_dir("orb_on_kitti_has_orb_slam3_distribution") else {
        return;
    };
    let image = common::kitti_frame(&data, 0, 0);
    let mut orb = OrbExtractor::new(OrbConfig::default()).unwrap_or_else(|e| panic!("{e}"));
    let features = orb.extract(image.view()).unwrap_or_else(|e| panic!("{e}"));
    let n = features.len();
    println!(
        "ORB on KITTI 06/000000: {n} keypoints in {:.1} ms",
        features.timings.total_ms
    );
    assert!((950..=1040).contains(&n), "{n} keypoints");
    assert_eq!(orb.name(), "orb");
    let DescriptorSet::Binary { data: rows } = &features.descriptors else {
        panic!("ORB must give binary descriptors");
    };
    assert_eq!(rows.len(), n);

    // Octaves close to the quotas.
    let quotas = &orb.scale_tables().features_per_level;
    let mut per_level = vec![0usize; quotas.len()];
    for kp in &features.keypoints {
        per_level[kp.octave as usize] += 1;
        let s = orb.scale_tables().scale_factors[kp.octave as usize];
        assert!((kp.size - 31.0 * s).abs() < 1e-3);
        assert!((0.0..360.0).contains(&kp.angle));
        assert!(
            kp.x >= 15.0 && kp.x < image.width() as f32 - 15.0,
            "x {}",
            kp.x
        );
        assert!(
            kp.y >= 15.0 && kp.y < image.height() as f32 - 15.0,
            "y {}",
            kp.y
        );
    }
    println!("per level {per_level:?}, quotas {quotas:?}");
    for (got, want) in per_level.iter().zip(quotas) {
        let diff = got.abs_diff(*want);
        assert!(diff <= 3 + want / 10, "level count {got} vs quota {want}");
    }

    // Spread: a 10x4 grid over the image has keypoints in most cells.
    let mut cells = [0usize; 40];
    for kp in &features.keypoints {
        let cx = ((kp.x / image.width() as f32) * 10.0) as usize;
        let cy = ((kp.y / image.height() as f32) * 4.0) as usize;
        cells[cy.min(3) * 10 + cx.min(9)] += 1;
    }
    let occupied = cells.iter().filter(|&&c| c > 0).count();
    let largest = cells.iter().max().copied().unwrap_or(0);
    println!("occupied cells {occupied}/40, largest cell {largest}");
    assert!(occupied >= 36, "{occupied} of 40 cells occupied");
    assert!(largest < n / 8, "one cell holds {largest} of {n}");

    // Deterministic.
    let again = orb.extract(image.view()).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(again.keypoints, features.keypoints);
    assert_eq!(again.descriptors, features.descriptors);
}

#[test]
fn orb_config_is_validated() {
    for config in [
        OrbConfig {
            n_features: 0,
            ..OrbConfig::default()
        },
        OrbConfig {
            scale_factor: 1.0,
            ..OrbConfig::default()
        },
        OrbConfig {
            min_th_fast: 30,
            ..OrbConfig::default()
        },
    ] {
        assert!(OrbExtractor::new(config).is_err(), "{config:?}");
    }
}

#[test]
fn orb_refuses_tiny_images_and_handles_flat_ones() {
    let mut orb = OrbExtractor::new(OrbConfig::default()).unwrap_or_else(|e| panic!("{e}"));
    let tiny = spslam::features::GrayImage::from_vec(vec![0; 8 * 8], 8, 8)
        .unwrap_or_else(|e| panic!("{e}"));
    assert!(orb.extract(tiny.view()).is_err());
    let flat = spslam::features::GrayImage::from_vec(vec![128; 200 * 100], 200, 100)
        .unwrap_or_else(|e| panic!("{e}"));
    let features = orb.extract(flat.view()).unwrap_or_else(|e| panic!("{e}"));
    assert!(features.is_empty());
    assert!(features.descriptors.is_empty());
}
