//! A slow machine, made deterministic: local mapping finishes each keyframe
//! only N frames after its work began (`SlamSystem::set_mapping_lag`, the
//! library side of `spslam run --mapping-lag N`; one frame when another
//! keyframe already waits and fusion and BA are skipped), so keyframes
//! queue and tracking sees the backlog, as with a 10 fps camera and local
//! mapping N times slower than on this machine. The stereo demo lap
//! (480×360, corners taken at 11.5° per frame) must still be tracked
//! frame by frame in one map.
//!
//! The lag of 5 is what the issue asks for (mapping five times slower).
//! It does not separate ORB-SLAM3's keyframe rule from spslam's here: both
//! track this lap. At a lag of 10 on the CLI's 480×360 lap, ORB-SLAM3's
//! rule lost 35 frames with SuperPoint + ANMS and spslam's none
//! (`tracking::keyframe::needs_keyframe`); on these frames, with the
//! tests' settings, a lag of 10 still loses frames 129–133 (open).

mod common;

use spslam::dataset::synthetic::SceneName;
use spslam::features::{FeatureExtractor, OrbConfig, OrbExtractor};
use spslam::settings::SlamSettings;
use spslam::system::SlamSystem;
use spslam::tracking::Frontend;

use common::synthetic_slam::{rig_of, run_against_truth, small_lap};

type ExtractorBox = Box<dyn FeatureExtractor>;

fn ok<T, E: std::fmt::Display>(r: Result<T, E>) -> T {
    r.unwrap_or_else(|e| panic!("{e}"))
}

/// Runs the lap with `extractor` (one per image) and local mapping `lag`
/// frames per keyframe; checks that every frame is tracked in one map
/// and that the ATE is at most `max_ate_percent` of the path.
fn check_lagged_lap(
    name: &str,
    extractor: &dyn Fn() -> ExtractorBox,
    lag: usize,
    max_ate_percent: f64,
) {
    let sequence = small_lap(SceneName::Loop);
    let rig = rig_of(&sequence);
    let mut slam = SlamSystem::new(rig, Frontend::new(extractor(), extractor(), &rig));
    if let Some(mapper) = slam.mapper_mut() {
        mapper.check_invariants = true;
    }
    ok(slam.set_mapping_lag(Some(lag)));
    let report = run_against_truth(&mut slam, &sequence);
    let summary = ok(slam.summary());
    let lost = common::untracked(slam.records());
    let maps: Vec<_> = summary
        .maps
        .iter()
        .filter(|m| m.merged_into.is_none())
        .collect();
    let ate_percent = 100.0 * report.ate.se3_rmse / report.path_length_m;
    eprintln!(
        "{name}, mapping lag {lag}: {} frames, lost {lost:?}, {} maps, {} keyframes, ATE {:.3} m ({ate_percent:.3} % of {:.1} m)",
        sequence.len(),
        maps.len(),
        summary.keyframes_inserted,
        report.ate.se3_rmse,
        report.path_length_m
    );
    assert!(lost.is_empty(), "frames not tracked: {lost:?}");
    assert_eq!(maps.len(), 1, "maps left unmerged: {:?}", summary.maps);
    assert!(
        ate_percent <= max_ate_percent,
        "ATE {ate_percent} % of the path > {max_ate_percent} %"
    );
}

#[test]
fn orb_tracks_the_whole_lap_when_mapping_lags_five_frames() {
    let orb = || -> ExtractorBox {
        Box::new(OrbExtractor::new(OrbConfig::default()).unwrap_or_else(|e| panic!("{e}")))
    };
    // Measured (Intel Xeon VNNI): ATE 0.397 m over 231.4 m (0.17 %); the
    // run without the lag drifts more on these frames, 1.41 m. The bound
    // leaves 2×.
    check_lagged_lap("ORB", &orb, 5, 0.35);
}

#[test]
fn superpoint_tracks_the_whole_lap_when_mapping_lags_five_frames() {
    let test = "superpoint_tracks_the_whole_lap_when_mapping_lags_five_frames";
    if !common::model_available(test) {
        return;
    }
    let sequence = small_lap(SceneName::Loop);
    let cam = *sequence.camera();
    let settings = SlamSettings::rectified_stereo(cam.fx, cam.fy, cam.cx, cam.cy, cam.baseline);
    let config = settings.extractor.superpoint_config(1, 1);
    let sp = || -> ExtractorBox { Box::new(common::extractor(config.clone())) };
    // Measured at e1d928d and at 64204f6 alike (Intel Xeon, AVX-512 VNNI):
    // ATE 1.747 m (0.755 % of 231.4 m), every frame tracked in one map;
    // the AMD EPYC (AVX2) CI run of 64204f6 passed the earlier bound of
    // 0.6 %. The int8 outputs differ between the CPU kinds, and so does
    // this lap's drift under the lag. The bound leaves 1.3× over the
    // larger of the two; what this test guards first is that the lagged
    // lap is tracked whole, in one map.
    check_lagged_lap("SuperPoint + ANMS", &sp, 5, 1.0);
}
