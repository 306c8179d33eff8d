//! Monocular SLAM (ORB, local mapping inline) on a synthetic city-block
//! sequence with exact ground truth: the two-view initialisation must
//! come within the first 30 frames, every frame after it must be tracked,
//! and the ATE after Sim3 alignment (the scale is unobservable) must stay
//! within 1 % of the path length.

mod common;

use common::sensor_runs::{orb_system, run_sensor, DepthNoise};
use common::synthetic_slam::small_sequence;
use spslam::camera::Sensor;
use spslam::dataset::synthetic::SceneName;
use spslam::eval::{ate, Alignment};
use spslam::tracking::{TrackingMethod, TrackingState};

/// Frames of the block loop (10 m/s at 10 fps).
const FRAMES: usize = 260;

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
    let lost = run.lost_from(first);
    let (truth, estimate) = run.trajectories_from(first);
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

#[test]
fn a_monocular_map_is_saved_reloaded_for_localisation_and_refused_by_a_stereo_system() {
    use spslam::storage::{load, DescriptorPrecision, SaveOptions};
    use spslam::system::{LoadedMapUse, MapProvenance};
    use spslam::tracking::SensorImages;

    let sequence = small_sequence(SceneName::Loop, 60);
    let mut slam = orb_system(&sequence, Sensor::Monocular);
    let first_pass = run_sensor(
        &sequence,
        &mut slam,
        Sensor::Monocular,
        DepthNoise::KINECT_TUM,
        0,
    );
    let dir = std::env::temp_dir().join(format!("spslam-mono-map-{}", std::process::id()));
    let _ = std::fs::create_dir_all(&dir);
    let path = dir.join("mono.spmap");
    let provenance = MapProvenance {
        extractor_settings: "orb".into(),
        model_hash: None,
        codebook_hash: None,
    };
    slam.save_map(
        &path,
        &provenance,
        DescriptorPrecision::F32,
        SaveOptions::default(),
    )
    .unwrap_or_else(|e| panic!("{e}"));

    // A stereo system is refused: a monocular map has no metric scale.
    let mut stereo = orb_system(&sequence, Sensor::Stereo);
    let refused = stereo
        .load_map(
            &path,
            load(&path).unwrap_or_else(|e| panic!("{e}")),
            &provenance,
            LoadedMapUse::LocaliseOnly,
        )
        .map(|_| ())
        .map_err(|e| e.to_string());
    assert!(
        matches!(&refused, Err(m) if m.contains("camera")),
        "{refused:?}"
    );

    // A monocular system localises in it, frames 30..60, adding nothing.
    let mut again = orb_system(&sequence, Sensor::Monocular);
    again
        .load_map(
            &path,
            load(&path).unwrap_or_else(|e| panic!("{e}")),
            &provenance,
            LoadedMapUse::LocaliseOnly,
        )
        .unwrap_or_else(|e| panic!("{e}"));
    let mut localised = 0;
    let mut worst: f64 = 0.0;
    for i in 30..60 {
        let frame = sequence.render(i, false);
        let image =
            spslam::features::GrayImage::from_vec(frame.left.clone(), frame.width, frame.height)
                .unwrap_or_else(|e| panic!("{e}"));
        let record = again
            .process_images(i, frame.timestamp, SensorImages::Monocular(image.view()))
            .unwrap_or_else(|e| panic!("frame {i}: {e}"));
        if record.state == TrackingState::Ok {
            localised += 1;
        }
    }
    let poses = again.trajectory().unwrap_or_else(|e| panic!("{e}"));
    for (k, (_, pose)) in poses.iter().enumerate() {
        let i = 30 + k;
        let d = (pose.to_isometry().translation.vector - first_pass.estimate[i].translation.vector)
            .norm();
        worst = worst.max(d);
    }
    let summary = again.summary().unwrap_or_else(|e| panic!("{e}"));
    eprintln!(
        "monocular map: {localised} of 30 frames localised, worst distance to the first pass {worst:.4} (map units), {} keyframes inserted",
        summary.keyframes_inserted
    );
    let _ = std::fs::remove_dir_all(&dir);
    assert!(localised >= 29, "{localised} of 30 localised");
    assert_eq!(summary.keyframes_inserted, 0);
    assert!(worst < 0.05, "worst distance {worst}");
}
