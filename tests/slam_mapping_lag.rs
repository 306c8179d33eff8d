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

use common::sensor_runs::{self, orb_system, run_sensor, DepthNoise};
use common::synthetic_slam::{rig_of, run_against_truth, small_lap};
use spslam::camera::Sensor;
use spslam::eval::{ate, Alignment};
use spslam::tracking::TrackingState;

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
    // Measured (Intel Xeon VNNI, 2026-11-29): ATE 0.303 m over 231.4 m (0.131 %); the
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
    let sp = || -> ExtractorBox { Box::new(common::cached_extractor(config.clone())) };
    // Measured at e1d928d and at 64204f6 alike (Intel Xeon, AVX-512 VNNI):
    // ATE 1.747 m (0.755 % of 231.4 m), every frame tracked in one map;
    // the AMD EPYC (AVX2) CI run of 64204f6 passed the earlier bound of
    // 0.6 %. The int8 outputs differ between the CPU kinds, and so does
    // this lap's drift under the lag. The bound leaves 1.3× over the
    // larger of the two; what this test guards first is that the lagged
    // lap is tracked whole, in one map.
    check_lagged_lap("SuperPoint + ANMS", &sp, 5, 1.0);
}

/// Runs the lap as `sensor` with ORB, mapping inline with `lag` frames per
/// keyframe (0: no lag); returns the untracked frames, the maps left
/// unmerged, the keyframes, the ATE as a percentage of the path (SE3,
/// Sim3 for monocular frames after the initialisation) and the local BAs
/// aborted by tracking's interrupts.
fn orb_sensor_lap(sensor: Sensor, lag: usize) -> (Vec<usize>, usize, usize, f64, usize) {
    let sequence = small_lap(SceneName::Loop);
    let slam = orb_system(&sequence, sensor);
    sensor_lap("ORB", &sequence, slam, sensor, lag)
}

/// [`orb_sensor_lap`] with SuperPoint + ANMS (int8, one level), RGB-D or
/// monocular.
fn superpoint_sensor_lap(sensor: Sensor, lag: usize) -> (Vec<usize>, usize, usize, f64, usize) {
    let sequence = small_lap(SceneName::Loop);
    let rig = sensor_runs::rig_for(&sequence, sensor);
    let cam = *sequence.camera();
    let settings = SlamSettings::rectified_stereo(cam.fx, cam.fy, cam.cx, cam.cy, cam.baseline);
    let config = settings.extractor.superpoint_config(1, 1);
    let frontend = ok(Frontend::single(
        Box::new(common::cached_extractor(config)),
        &rig,
    ));
    let mut slam = SlamSystem::new(rig, frontend);
    if let Some(mapper) = slam.mapper_mut() {
        mapper.check_invariants = true;
    }
    sensor_lap("SuperPoint + ANMS", &sequence, slam, sensor, lag)
}

/// Runs `slam` over the lap (see [`orb_sensor_lap`]).
fn sensor_lap(
    name: &str,
    sequence: &spslam::dataset::synthetic::SyntheticSequence,
    mut slam: SlamSystem,
    sensor: Sensor,
    lag: usize,
) -> (Vec<usize>, usize, usize, f64, usize) {
    if lag > 0 {
        ok(slam.set_mapping_lag(Some(lag)));
    }
    let run = run_sensor(sequence, &mut slam, sensor, DepthNoise::KINECT_TUM, 0);
    let summary = ok(slam.summary());
    let maps = summary
        .maps
        .iter()
        .filter(|m| m.merged_into.is_none())
        .count();
    let first = run
        .records
        .iter()
        .find(|r| r.state == TrackingState::Ok)
        .map_or(0, |r| r.index);
    let lost = run.lost_from(first);
    let (truth, estimate) = run.trajectories_from(first);
    let alignment = if sensor == Sensor::Monocular {
        Alignment::Sim3
    } else {
        Alignment::Se3
    };
    let result = ok(ate(&truth, &estimate, alignment));
    let percent = 100.0 * result.stats.rmse / run.path_length();
    eprintln!(
        "{name} {sensor:?}, mapping lag {lag}: lost {lost:?}, {maps} maps, {} keyframes, ATE {:.3} m ({percent:.3} % of {:.1} m)",
        summary.keyframes_inserted,
        result.stats.rmse,
        run.path_length()
    );
    let interrupted = run
        .records
        .iter()
        .filter(|r| r.mapping.as_ref().is_some_and(|m| m.bundle.aborted))
        .count();
    (lost, maps, summary.keyframes_inserted, percent, interrupted)
}

#[test]
fn rgbd_tracks_the_whole_lap_when_mapping_lags_five_frames_as_well_as_without_the_lag() {
    let (lost, maps, _, quiet, _) = orb_sensor_lap(Sensor::Rgbd, 0);
    assert!(
        lost.is_empty() && maps == 1,
        "without the lag: lost {lost:?}, {maps} maps"
    );
    let (lost, maps, _, lagged, interrupted) = orb_sensor_lap(Sensor::Rgbd, 5);
    assert_eq!(interrupted, 0, "an RGB-D run interrupted local BAs");
    assert!(lost.is_empty(), "frames not tracked: {lost:?}");
    assert_eq!(maps, 1, "maps left unmerged");
    // Measured (Intel Xeon VNNI; ORB's outputs do not depend on the CPU
    // kind): 0.077 % of the path with and without the lag (0.179 and
    // 0.178 m over 231.4 m). The bound: within 1.5× of the quiet
    // run; and 2× over the measured fraction of the path.
    assert!(
        lagged <= 1.5 * quiet,
        "ATE {lagged:.3} % with the lag, {quiet:.3} % without"
    );
    assert!(lagged <= 0.15, "ATE {lagged:.3} % of the path");
}

/// SuperPoint + ANMS's RGB-D lap when mapping lags five frames. Under the
/// lag the reference keyframe's points lack what local mapping adds, and
/// in the turns the motion model fails; tracking then rests on descriptor
/// matches with the reference keyframe or the last frame, whose ratio test
/// must not pit two of that view's points within one descriptor cell
/// against each other (`tracking::search::match_descriptors_in_view`).
/// Measured (AMD EPYC, AVX2, 2026-12-02): with the plain ratio test 15 of
/// frames 136–152 were lost, in 4 maps (ATE 25.6 m); with the rivals beyond
/// the cell every frame is tracked in one map, ATE 3.84 m (1.66 % of
/// 231.4 m, the tests' Kinect-like depth noise on a lap whose turns are
/// taken at 11.5° per frame). What this guards first is every frame in one
/// map; the ATE bound leaves 1.8× over the measurement, as the int8
/// outputs, and so the drift, differ between CPU kinds.
#[test]
fn superpoint_rgbd_tracks_the_whole_lap_when_mapping_lags_five_frames() {
    let test = "superpoint_rgbd_tracks_the_whole_lap_when_mapping_lags_five_frames";
    if !common::model_available(test) {
        return;
    }
    let (lost, maps, _, lagged, interrupted) = superpoint_sensor_lap(Sensor::Rgbd, 5);
    assert_eq!(interrupted, 0, "an RGB-D run interrupted local BAs");
    assert!(lost.is_empty(), "frames not tracked: {lost:?}");
    assert_eq!(maps, 1, "maps left unmerged");
    assert!(lagged <= 3.0, "ATE {lagged:.3} % of the path");
}

/// Monocular tracking when mapping lags (issue 25's target is every frame;
/// not met). A monocular camera's new points come only from local
/// mapping's triangulation, so keyframes that wait for a slow mapper leave
/// tracking without points in the turns. The monocular rule (weak frames
/// are keyframes through condition 1c: `tracking::keyframe::needs_keyframe`)
/// took this lap from 72 lost frames in 12 maps to 15 in 4 (three of its
/// four corners, 5 frames each) when a keyframe wanted while mapping was
/// busy interrupted its BA every time; with ORB-SLAM3's condition for the
/// interrupt (1a or 1c, session 43) 5 frames are lost, at the third
/// corner, in 2 maps, with 94 keyframes (51 with ORB-SLAM3's rule of no
/// monocular keyframe while mapping is busy). Since an interrupted BA
/// keeps the share of its iterations it had time for (session 47; it had
/// none before) no frame is lost: 2 maps, 95 keyframes, 26 BAs cut, ATE
/// 6.205 m Sim3 (2.68 % of the path). The run without the lag tracks
/// every frame (0.552 m Sim3, 0.24 % of the path). The bounds guard the
/// gain with a corner's margin (5 frames); ORB's outputs do not depend on
/// the CPU kind.
#[test]
fn monocular_keeps_the_lap_but_its_corners_when_mapping_lags_five_frames() {
    let (lost, maps, keyframes, _, interrupted) = orb_sensor_lap(Sensor::Monocular, 5);
    assert!(lost.len() <= 5, "{} frames lost: {lost:?}", lost.len());
    assert!(maps <= 3, "{maps} maps");
    assert!(keyframes >= 80, "{keyframes} keyframes");
    assert!(interrupted > 0, "no BA was interrupted");
}
