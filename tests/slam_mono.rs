//! Monocular SLAM (ORB, local mapping inline) on a synthetic city-block
//! sequence with exact ground truth: the two-view initialisation must
//! come within the first 30 frames, every frame after it must be tracked,
//! and the ATE after Sim3 alignment (the scale is unobservable) must stay
//! within 1 % of the path length.

mod common;

use common::sensor_runs::{orb_system, run_sensor, DepthNoise, SensorRun};
use common::synthetic_slam::small_sequence;
use spslam::camera::Sensor;
use spslam::dataset::synthetic::SceneName;
use spslam::eval::{ate, Alignment, Trajectory};
use spslam::tracking::{TrackingMethod, TrackingState};

/// Frames of the block loop (10 m/s at 10 fps).
const FRAMES: usize = 260;

/// The frames from `first` on, as trajectories.
fn from_frame(run: &SensorRun, first: usize) -> (Trajectory, Trajectory) {
    let keep: Vec<usize> = (first..run.truth.len()).collect();
    let (truth, estimate) = run.trajectories();
    (truth.select(&keep), estimate.select(&keep))
}

#[test]
fn monocular_initialises_within_30_frames_and_tracks_within_1_percent_of_the_path() {
    let sequence = small_sequence(SceneName::Loop, FRAMES);
    let mut slam = orb_system(&sequence, Sensor::Monocular);
    let run = run_sensor(
        &sequence,
        &mut slam,
        Sensor::Monocular,
        DepthNoise::KINECT_TUM,
        0,
    );
    let init = run
        .records
        .iter()
        .filter(|r| r.method == TrackingMethod::Initialisation)
        .map(|r| r.index)
        .collect::<Vec<_>>();
    let Some(&first) = init.first() else {
        panic!("monocular initialisation never happened");
    };
    let last_init = init.last().copied().unwrap_or(first);
    let lost: Vec<usize> = run
        .records
        .iter()
        .filter(|r| r.index >= first && r.state != TrackingState::Ok)
        .map(|r| r.index)
        .collect();
    let (truth, estimate) = from_frame(&run, first);
    let path: f64 = truth
        .poses
        .windows(2)
        .map(|w| (w[1].translation.vector - w[0].translation.vector).norm())
        .sum();
    let result = ate(&truth, &estimate, Alignment::Sim3).unwrap_or_else(|e| panic!("{e}"));
    let keyframes = run.records.iter().filter(|r| r.keyframe).count();
    eprintln!(
        "monocular: initialised with frames {first} and {last_init}; {} frames lost after; {keyframes} keyframes; \
         ATE (Sim3) {:.4} m = {:.3} % of {path:.1} m; scale {:.3}",
        lost.len(),
        result.stats.rmse,
        100.0 * result.stats.rmse / path,
        result.scale
    );
    assert!(last_init < 30, "initialised at frame {last_init}");
    assert!(
        lost.is_empty(),
        "frames lost after initialisation: {lost:?}"
    );
    assert!(
        result.stats.rmse <= 0.01 * path,
        "ATE {:.4} m over a {path:.1} m path",
        result.stats.rmse
    );
}
