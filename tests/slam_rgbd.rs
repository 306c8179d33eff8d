//! RGB-D SLAM (ORB, local mapping inline) on a synthetic city-block loop
//! whose rendered depth gets a structured-light camera's noise (1/5000 m
//! steps, 10 % of the pixels missing, Nguyen's axial noise, 13.1 m at
//! most), against the stereo run on the same images and the exact ground
//! truth. And the bad-input side: a depth image of the wrong size.

mod common;

use common::sensor_runs::{orb_system, run_sensor, DepthNoise, SensorRun};
use common::synthetic_slam::small_sequence;
use spslam::camera::{DepthImage, Sensor};
use spslam::dataset::synthetic::SceneName;
use spslam::error::SlamError;
use spslam::eval::{ate, Alignment};
use spslam::features::GrayImage;
use spslam::tracking::SensorImages;

/// One lap of the block and a little more (10 m/s at 10 fps).
const FRAMES: usize = 260;

fn ate_of(run: &SensorRun) -> f64 {
    let (truth, estimate) = run.trajectories();
    ate(&truth, &estimate, Alignment::Se3)
        .unwrap_or_else(|e| panic!("{e}"))
        .stats
        .rmse
}

#[test]
fn rgbd_on_a_noisy_synthetic_loop_tracks_every_frame_within_1_5x_stereo_ate() {
    let sequence = small_sequence(SceneName::Loop, FRAMES);
    let depth0 = sequence.render(0, true);
    let depth = DepthNoise::KINECT_TUM.apply(&depth0, &mut common::rng::Rng::new(1));
    eprintln!(
        "frame 0: median rendered depth {:?} m, {:.1} % of the pixels with a noisy depth",
        depth.median_valid(),
        100.0 * depth.as_slice().iter().filter(|d| **d > 0.0).count() as f64
            / depth.as_slice().len() as f64
    );
    let mut stereo_slam = orb_system(&sequence, Sensor::Stereo);
    let stereo = run_sensor(
        &sequence,
        &mut stereo_slam,
        Sensor::Stereo,
        DepthNoise::KINECT_TUM,
        7,
    );
    let mut rgbd_slam = orb_system(&sequence, Sensor::Rgbd);
    let rgbd = run_sensor(
        &sequence,
        &mut rgbd_slam,
        Sensor::Rgbd,
        DepthNoise::KINECT_TUM,
        7,
    );
    let (stereo_ate, rgbd_ate) = (ate_of(&stereo), ate_of(&rgbd));
    let keyframes = |run: &SensorRun| run.records.iter().filter(|r| r.keyframe).count();
    eprintln!(
        "RGB-D: ATE {rgbd_ate:.4} m ({} keyframes); stereo: ATE {stereo_ate:.4} m ({} keyframes); ratio {:.2}; path {:.1} m",
        keyframes(&rgbd),
        keyframes(&stereo),
        rgbd_ate / stereo_ate,
        rgbd.path_length()
    );
    let lost = common::untracked(&rgbd.records);
    assert!(lost.is_empty(), "RGB-D frames not tracked: {lost:?}");
    assert!(
        common::untracked(&stereo.records).is_empty(),
        "the stereo reference lost frames"
    );
    assert!(
        rgbd_ate <= 1.5 * stereo_ate,
        "RGB-D ATE {rgbd_ate:.4} m is more than 1.5x stereo's {stereo_ate:.4} m"
    );
}

#[test]
fn a_depth_image_of_another_size_is_a_typed_error_and_the_system_goes_on() {
    let sequence = small_sequence(SceneName::Loop, 3);
    let mut slam = orb_system(&sequence, Sensor::Rgbd);
    let frame = sequence.render(0, true);
    let image = GrayImage::from_vec(frame.left.clone(), frame.width, frame.height)
        .unwrap_or_else(|e| panic!("{e}"));
    let small =
        DepthImage::from_metres(vec![1.0; 64 * 48], 64, 48).unwrap_or_else(|e| panic!("{e}"));
    let err = slam
        .process_images(
            0,
            0.0,
            SensorImages::Rgbd {
                image: image.view(),
                depth: &small,
            },
        )
        .map(|_| ())
        .unwrap_err();
    assert!(
        matches!(
            err,
            SlamError::DepthSizeMismatch {
                frame: 0,
                depth_width: 64,
                ..
            }
        ),
        "{err}"
    );
    // Stereo images given to an RGB-D system: named, not a panic.
    let err = slam
        .process_images(
            0,
            0.0,
            SensorImages::Stereo {
                left: image.view(),
                right: image.view(),
            },
        )
        .map(|_| ())
        .unwrap_err();
    assert!(matches!(err, SlamError::SensorMismatch { .. }), "{err}");
    // The next good frame initialises.
    let depth = DepthNoise::KINECT_TUM.apply(&frame, &mut common::rng::Rng::new(3));
    let record = slam
        .process_images(
            0,
            0.0,
            SensorImages::Rgbd {
                image: image.view(),
                depth: &depth,
            },
        )
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(record.state, spslam::tracking::TrackingState::Ok);
}
