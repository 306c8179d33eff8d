//! Stereo matching: SuperPoint on a KITTI 06 pair checked against a dense
//! StereoSGBM reference, ORB's Hamming path on the same pair, and a synthetic
//! periodic scene where a decoy one descriptor cell (8 px) off must never win.

mod common;

use spslam::features::pyramid::ScaleTables;
use spslam::features::{
    DescriptorSet, ExtractorConfig, FeatureExtractor, FrameFeatures, GrayImage, Keypoint,
    OrbConfig, OrbExtractor, Precision,
};
use spslam::matching::dense::sgbm_disparity;
use spslam::matching::{
    match_stereo, DistanceThresholds, PeriodicGuard, StereoImages, StereoOutcome, StereoParams,
};

/// KITTI 06: fx = 707.0912, bf = 379.8145, baseline 0.537 m.
const KITTI_BF: f32 = 379.8145;
const KITTI_BASELINE: f32 = 0.537_14;

/// Share of matches whose disparity is within `tol` px of SGBM's (where SGBM is valid).
fn agreement(
    left: &FrameFeatures,
    outcome: &StereoOutcome,
    sgbm: &spslam::matching::dense::DisparityMap,
    tol: f32,
) -> (usize, usize) {
    let (mut checked, mut good) = (0, 0);
    for (kp, m) in left.keypoints.iter().zip(&outcome.matches) {
        let (Some(m), Some(d)) = (m, sgbm.at(kp.x, kp.y)) else {
            continue;
        };
        checked += 1;
        good += usize::from((kp.x - m.right_u - d).abs() <= tol);
    }
    (checked, good)
}

/// The stereo check of one precision; returns the fraction of left
/// keypoints matched by the default (guarded) matcher.
fn superpoint_stereo_check(data: &std::path::Path, precision: Precision) -> f32 {
    let (left_img, right_img) = (
        common::kitti_frame(data, 0, 0),
        common::kitti_frame(data, 1, 0),
    );
    let mut sp = common::extractor(ExtractorConfig {
        precision,
        ..ExtractorConfig::default()
    });
    let left =
        FeatureExtractor::extract(&mut sp, left_img.view()).unwrap_or_else(|e| panic!("{e}"));
    let right =
        FeatureExtractor::extract(&mut sp, right_img.view()).unwrap_or_else(|e| panic!("{e}"));
    let tables = FeatureExtractor::scale_tables(&sp).clone();
    let images = StereoImages {
        left: left_img.view(),
        right: right_img.view(),
    };
    let sgbm =
        sgbm_disparity(left_img.view(), right_img.view(), 160).unwrap_or_else(|e| panic!("{e}"));
    let th = DistanceThresholds::SUPERPOINT_L2.stereo();
    let guarded = StereoParams::new(
        KITTI_BF,
        KITTI_BASELINE,
        th,
        Some(PeriodicGuard::SUPERPOINT),
    );
    let variants = [
        ("guarded (default)", guarded),
        (
            "no periodic guard",
            StereoParams {
                periodic: None,
                ..guarded
            },
        ),
        (
            "no guard, no ratio",
            StereoParams {
                periodic: None,
                ratio: None,
                ..guarded
            },
        ),
    ];
    let mut figures = Vec::new();
    for (name, params) in variants {
        let outcome =
            match_stereo(&left, &right, images, &tables, &params).unwrap_or_else(|e| panic!("{e}"));
        let (checked, good) = agreement(&left, &outcome, &sgbm, 1.5);
        let (_, good2) = agreement(&left, &outcome, &sgbm, 2.0);
        let (_, good3) = agreement(&left, &outcome, &sgbm, 3.0);
        let off_by_cell = left
            .keypoints
            .iter()
            .zip(&outcome.matches)
            .filter(|(kp, m)| {
                m.zip(sgbm.at(kp.x, kp.y))
                    .is_some_and(|(m, d)| ((kp.x - m.right_u - d).abs() - 8.0).abs() <= 1.5)
            })
            .count();
        println!(
            "{precision} {name}: {} matches of {}; vs SGBM: {good}/{checked} within 1.5 px ({:.1}%), {good2} within 2 px, {good3} within 3 px, {off_by_cell} one cell (8 px) off; rejections {:?}",
            outcome.matched(),
            left.len(),
            100.0 * good as f32 / checked.max(1) as f32,
            outcome.rejections
        );
        figures.push((outcome.matched(), checked, good2, off_by_cell));
    }
    let (matched, checked, good, off_by_cell) = figures[0];
    assert!(matched >= 250, "only {matched} stereo matches");
    assert!(checked >= 200, "only {checked} matches where SGBM is valid");
    assert!(
        good as f32 >= 0.95 * checked as f32,
        "{good}/{checked} agree with SGBM within 2 px"
    );
    assert!(
        off_by_cell as f32 <= 0.01 * checked as f32,
        "{off_by_cell} matches one cell off"
    );
    for m in figures.iter().skip(1) {
        assert!(m.0 >= matched, "the guards can only remove matches");
    }
    matched as f32 / left.len().max(1) as f32
}

/// ORB-SLAM3's `ComputeStereoMatches` for binary rows: ORB's Hamming stereo
/// threshold, no ratio test along the row, no periodic guard.
fn orb_slam3_hamming_params() -> StereoParams {
    StereoParams {
        ratio: None,
        ..StereoParams::new(
            KITTI_BF,
            KITTI_BASELINE,
            DistanceThresholds::ORB_HAMMING.stereo(),
            None,
        )
    }
}

/// Matches a KITTI pair's features along rows and computes SGBM's
/// disparity of the same images, the reference.
fn match_rows_with_sgbm(
    (left, right): (&FrameFeatures, &FrameFeatures),
    (left_img, right_img): (&GrayImage, &GrayImage),
    tables: &ScaleTables,
    params: &StereoParams,
) -> (StereoOutcome, spslam::matching::dense::DisparityMap) {
    let outcome = match_stereo(
        left,
        right,
        StereoImages {
            left: left_img.view(),
            right: right_img.view(),
        },
        tables,
        params,
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let sgbm =
        sgbm_disparity(left_img.view(), right_img.view(), 160).unwrap_or_else(|e| panic!("{e}"));
    (outcome, sgbm)
}

#[test]
fn superpoint_stereo_on_kitti_agrees_with_sgbm() {
    let Some(data) = common::setup("superpoint_stereo_on_kitti_agrees_with_sgbm") else {
        return;
    };
    let fp32 = superpoint_stereo_check(&data, Precision::Fp32);
    let int8 = superpoint_stereo_check(&data, Precision::Int8);
    println!(
        "stereo match fraction: fp32 {:.3}, int8 {:.3} ({:+.1} points)",
        fp32,
        int8,
        100.0 * (int8 - fp32)
    );
    // The int8 network must not cost stereo matches (the bound is 1
    // point; the test allows 2 for another machine's kernels).
    assert!(
        int8 >= fp32 - 0.02,
        "int8 matches {int8:.3} of the keypoints, fp32 {fp32:.3}"
    );
}

#[test]
fn orb_hamming_stereo_on_kitti() {
    let Some(data) = common::data_dir("orb_hamming_stereo_on_kitti") else {
        return;
    };
    let (left_img, right_img) = (
        common::kitti_frame(&data, 0, 0),
        common::kitti_frame(&data, 1, 0),
    );
    let mut orb = OrbExtractor::new(OrbConfig::default()).unwrap_or_else(|e| panic!("{e}"));
    let left = orb
        .extract(left_img.view())
        .unwrap_or_else(|e| panic!("{e}"));
    let right = orb
        .extract(right_img.view())
        .unwrap_or_else(|e| panic!("{e}"));
    // ORB-SLAM3 has no ratio test along the row for ORB.
    let params = orb_slam3_hamming_params();
    let (outcome, sgbm) = match_rows_with_sgbm(
        (&left, &right),
        (&left_img, &right_img),
        orb.scale_tables(),
        &params,
    );
    let (checked, good) = agreement(&left, &outcome, &sgbm, 1.5);
    println!(
        "ORB: {} matches of {}; vs SGBM {good}/{checked} within 1.5 px; rejections {:?}",
        outcome.matched(),
        left.len(),
        outcome.rejections
    );
    assert!(
        outcome.matched() >= 250,
        "{} ORB stereo matches",
        outcome.matched()
    );
    assert!(
        good as f32 >= 0.9 * checked as f32,
        "{good}/{checked} agree with SGBM"
    );
    for (kp, m) in left
        .keypoints
        .iter()
        .zip(&outcome.matches)
        .filter_map(|(k, m)| m.map(|m| (k, m)))
    {
        assert!(m.right_u <= kp.x && m.depth > 0.0);
        assert!(m.distance <= DistanceThresholds::ORB_HAMMING.stereo());
    }
}

/// A deterministic pseudo-random texture value.
fn noise(seed: u64) -> u8 {
    let mut x = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ 0xd1b5_4a32_d192_ed03;
    x ^= x >> 31;
    x = x.wrapping_mul(0xbf58_476d_1ce4_e5b9);
    x ^= x >> 29;
    (x % 200) as u8 + 20
}

const W: usize = 240;
const H: usize = 64;
const DISPARITY: usize = 24;

/// Left image and the right one (left shifted by DISPARITY, plus slight noise).
/// `periodic`: the texture repeats every 8 columns.
fn scene(periodic: bool) -> (GrayImage, GrayImage) {
    let tex = |x: usize, y: usize| {
        let col = if periodic { x % 8 } else { x };
        // Smooth over 2x2 so the SAD curve has a clear minimum.
        let v = |cx: usize, cy: usize| noise((cy as u64 / 2) * 10_007 + cx as u64 / 2) as u32;
        ((v(col, y) + v(col + 1, y) + v(col, y + 1) + v(col + 1, y + 1)) / 4) as u8
    };
    let left: Vec<u8> = (0..W * H).map(|i| tex(i % W, i / W)).collect();
    let right: Vec<u8> = (0..W * H)
        .map(|i| {
            let (x, y) = (i % W, i / W);
            let v = tex(x + DISPARITY, y) as i32 + (noise(i as u64 + 77) as i32 % 3) - 1;
            v.clamp(0, 255) as u8
        })
        .collect();
    let img = |p: Vec<u8>| GrayImage::from_vec(p, W, H).unwrap_or_else(|e| panic!("{e}"));
    (img(left), img(right))
}

fn kp(x: f32, y: f32) -> Keypoint {
    Keypoint {
        x,
        y,
        size: 31.0,
        angle: 0.0,
        response: 1.0,
        octave: 0,
    }
}

/// A unit 4-vector near axis `axis`, perturbed by `eps` on the next axis.
fn unit(axis: usize, eps: f32) -> [f32; 4] {
    let mut v = [0.0f32; 4];
    v[axis] = 1.0;
    v[(axis + 1) % 4] = eps;
    let n = (1.0 + eps * eps).sqrt();
    v.map(|x| x / n)
}

/// Left keypoints at rows 16, 24, 32, 40, 48 (column 120); right keypoints at
/// the true positions (`with_truth`) and decoys 8 px further left, whose
/// descriptors are near-equal to the true ones (slightly closer).
fn periodic_case(with_truth: bool) -> (FrameFeatures, FrameFeatures) {
    let rows = [16.0f32, 24.0, 32.0, 40.0, 48.0];
    let mut left_kps = Vec::new();
    let mut left_desc = Vec::new();
    let mut right_kps = Vec::new();
    let mut right_desc = Vec::new();
    for (k, &y) in rows.iter().enumerate() {
        let axis = k % 4;
        left_kps.push(kp(120.0, y));
        left_desc.extend(unit(axis, 0.0));
        let true_u = 120.0 - DISPARITY as f32;
        if with_truth {
            right_kps.push(kp(true_u, y));
            right_desc.extend(unit(axis, 0.06));
        }
        right_kps.push(kp(true_u - 8.0, y));
        right_desc.extend(unit(axis, 0.05));
    }
    let set = |keypoints: Vec<Keypoint>, data: Vec<f32>| FrameFeatures {
        keypoints,
        descriptors: DescriptorSet::Float { dim: 4, data },
        timings: Default::default(),
    };
    (set(left_kps, left_desc), set(right_kps, right_desc))
}

#[test]
fn a_decoy_one_cell_off_is_never_chosen() {
    let tables = ScaleTables::new(1000, 1.2, 1);
    let true_u = 120.0 - DISPARITY as f32;
    let guarded = StereoParams::new(100.0, 0.5, 0.7, Some(PeriodicGuard::SUPERPOINT));
    for periodic_texture in [false, true] {
        let (l_img, r_img) = scene(periodic_texture);
        let images = StereoImages {
            left: l_img.view(),
            right: r_img.view(),
        };
        for with_truth in [true, false] {
            let (left, right) = periodic_case(with_truth);
            let outcome = match_stereo(&left, &right, images, &tables, &guarded)
                .unwrap_or_else(|e| panic!("{e}"));
            println!(
                "periodic texture {periodic_texture}, true keypoint present {with_truth}: {} matched, {:?}",
                outcome.matched(),
                outcome.rejections
            );
            for m in outcome.matches.iter().flatten() {
                assert!(
                    (m.right_u - true_u).abs() < 1.0,
                    "decoy chosen: right_u {} (truth {true_u})",
                    m.right_u
                );
            }
        }
    }
    // Without the guards and the ratio test, the periodic scene does fool the
    // matcher: the check above is not vacuous.
    let (l_img, r_img) = scene(true);
    let images = StereoImages {
        left: l_img.view(),
        right: r_img.view(),
    };
    let (left, right) = periodic_case(false);
    let unguarded = StereoParams {
        periodic: None,
        ratio: None,
        ..guarded
    };
    let outcome =
        match_stereo(&left, &right, images, &tables, &unguarded).unwrap_or_else(|e| panic!("{e}"));
    let fooled = outcome
        .matches
        .iter()
        .flatten()
        .filter(|m| (m.right_u - (true_u - 8.0)).abs() < 1.0)
        .count();
    assert!(
        fooled > 0,
        "expected the unguarded matcher to take the decoy"
    );
}

#[test]
fn a_clean_synthetic_pair_is_matched_at_the_true_disparity() {
    let tables = ScaleTables::new(1000, 1.2, 1);
    let (l_img, r_img) = scene(false);
    let left = FrameFeatures {
        keypoints: (0..5)
            .map(|k| kp(60.0 + 30.0 * k as f32, 16.0 + 8.0 * k as f32))
            .collect(),
        descriptors: DescriptorSet::Float {
            dim: 4,
            data: (0..5).flat_map(|k| unit(k % 4, 0.0)).collect(),
        },
        timings: Default::default(),
    };
    let right = FrameFeatures {
        keypoints: left
            .keypoints
            .iter()
            .map(|k| kp(k.x - DISPARITY as f32 + 0.4, k.y))
            .collect(),
        descriptors: DescriptorSet::Float {
            dim: 4,
            data: (0..5).flat_map(|k| unit(k % 4, 0.1)).collect(),
        },
        timings: Default::default(),
    };
    let params = StereoParams::new(100.0, 0.5, 0.7, Some(PeriodicGuard::SUPERPOINT));
    let images = StereoImages {
        left: l_img.view(),
        right: r_img.view(),
    };
    let outcome =
        match_stereo(&left, &right, images, &tables, &params).unwrap_or_else(|e| panic!("{e}"));
    println!("clean: {:?}", outcome.rejections);
    assert_eq!(outcome.matched(), 5, "{:?}", outcome.rejections);
    for (kp, m) in left.keypoints.iter().zip(outcome.matches.iter().flatten()) {
        assert!(
            (kp.x - m.right_u - DISPARITY as f32).abs() < 0.5,
            "disparity {}",
            kp.x - m.right_u
        );
        assert!((m.depth - 100.0 / (kp.x - m.right_u)).abs() < 1e-3);
    }
}

/// The binary mode as an unmodified ORB-SLAM3 would use it: SuperPoint's
/// fp32 descriptors reduced to their sign bits (ORB's 32-byte layout),
/// matched with ORB's Hamming thresholds and no ratio test or periodic
/// guard (ORB-SLAM3's `ComputeStereoMatches`). Compared with SGBM, next to
/// the float mode's figures (printed by the test above) and ORB's.
#[test]
fn superpoint_binary_mode_stereo_on_kitti() {
    let Some(data) = common::setup("superpoint_binary_mode_stereo_on_kitti") else {
        return;
    };
    let (left_img, right_img) = (
        common::kitti_frame(&data, 0, 0),
        common::kitti_frame(&data, 1, 0),
    );
    let mut sp = common::extractor(ExtractorConfig {
        precision: Precision::Fp32,
        ..ExtractorConfig::default()
    });
    let to_binary = |f: FrameFeatures| {
        let DescriptorSet::Float { dim, data } = &f.descriptors else {
            panic!("SuperPoint gives float rows");
        };
        let mut bytes = Vec::new();
        spslam::features::sign_bits::pack_sign_bits(data, *dim, &mut bytes);
        let rows = bytes
            .chunks_exact(32)
            .map(|c| {
                let mut row = [0u8; 32];
                row.copy_from_slice(c);
                row
            })
            .collect();
        FrameFeatures {
            descriptors: DescriptorSet::Binary { data: rows },
            ..f
        }
    };
    let left = to_binary(
        FeatureExtractor::extract(&mut sp, left_img.view()).unwrap_or_else(|e| panic!("{e}")),
    );
    let right = to_binary(
        FeatureExtractor::extract(&mut sp, right_img.view()).unwrap_or_else(|e| panic!("{e}")),
    );
    let (outcome, sgbm) = match_rows_with_sgbm(
        (&left, &right),
        (&left_img, &right_img),
        FeatureExtractor::scale_tables(&sp),
        &orb_slam3_hamming_params(),
    );
    let (checked, good) = agreement(&left, &outcome, &sgbm, 1.5);
    let (_, good2) = agreement(&left, &outcome, &sgbm, 2.0);
    println!(
        "SuperPoint binary mode (sign bits, Hamming <= {}): {} matches of {}; vs SGBM {good}/{checked} within 1.5 px ({:.1}%), {good2} within 2 px; rejections {:?}",
        DistanceThresholds::ORB_HAMMING.stereo(),
        outcome.matched(),
        left.len(),
        100.0 * good as f32 / checked.max(1) as f32,
        outcome.rejections
    );
    assert!(
        outcome.matched() >= 250,
        "{} binary stereo matches",
        outcome.matched()
    );
    // Measured: 597 matches, 86.6 % within 2 px (451/521): more matches
    // but less precise than the float mode (372, 95 %) and ORB (400, 93 %
    // within 1.5 px); ORB's 75-bit threshold admits more row decoys for
    // sign bits. A regression bound, not a quality claim.
    assert!(
        good2 as f32 >= 0.84 * checked as f32,
        "{good2}/{checked} agree with SGBM within 2 px"
    );
}
