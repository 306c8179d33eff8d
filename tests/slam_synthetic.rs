//! Stereo SLAM (ORB, local mapping inline) on 500-frame synthetic
//! sequences rendered in memory, against their exact ground truth: a
//! straight street (500 m) and a city-block loop (two laps and more, 500 m).
//! Every frame must be tracked; the drift is printed and bounded.
//!
//! The images are rendered at 480×360 (focal 300 px, the default field of
//! view) to keep the suite's time down; `EVALUATION.md` has the 640×480
//! runs through `spslam run`.

mod common;

use common::synthetic_slam::{cached_images, images, orb_slam, small_sequence};
use nalgebra::Isometry3;
use spslam::dataset::synthetic::SceneName;
use spslam::eval::{evaluate, EvalOptions, Pairing, Trajectory};
use spslam::features::GrayImage;
use spslam::tracking::TrackingState;

/// Frames per sequence (10 m/s at 10 fps: 500 m).
const FRAMES: usize = 500;

/// One run: the frames not tracked, the estimate and the ground truth
/// (both as `T_wc` relative to the first frame).
struct SyntheticRun {
    lost: Vec<usize>,
    estimate: Vec<Isometry3<f64>>,
    truth: Vec<Isometry3<f64>>,
    timestamps: Vec<f64>,
}

impl SyntheticRun {
    fn path_length(&self) -> f64 {
        self.truth
            .windows(2)
            .map(|w| (w[1].translation.vector - w[0].translation.vector).norm())
            .sum()
    }

    /// Final-position error over the path length, percent.
    fn final_drift_percent(&self) -> f64 {
        let (Some(e), Some(t)) = (self.estimate.last(), self.truth.last()) else {
            return f64::INFINITY;
        };
        100.0 * (e.translation.vector - t.translation.vector).norm() / self.path_length()
    }

    /// Position RMSE without alignment (both start at the identity), metres.
    fn unaligned_rmse(&self) -> f64 {
        let sum: f64 = self
            .estimate
            .iter()
            .zip(&self.truth)
            .map(|(e, t)| (e.translation.vector - t.translation.vector).norm_squared())
            .sum();
        (sum / self.truth.len().max(1) as f64).sqrt()
    }

    fn trajectories(&self) -> (Trajectory, Trajectory) {
        (
            Trajectory::new(self.timestamps.clone(), self.truth.clone()),
            Trajectory::new(self.timestamps.clone(), self.estimate.clone()),
        )
    }
}

fn run_orb_slam(scene: SceneName) -> SyntheticRun {
    run_orb_slam_with(scene, FRAMES, false).0
}

/// Runs `frames` frames of `scene`, local mapping on its own thread when
/// `threaded`; also returns the frame records.
fn run_orb_slam_with(
    scene: SceneName,
    frames: usize,
    threaded: bool,
) -> (SyntheticRun, Vec<spslam::system::FrameRecord>) {
    let sequence = small_sequence(scene, frames);
    let mut slam = orb_slam(&sequence);
    if threaded {
        slam.spawn_mapping_thread()
            .unwrap_or_else(|e| panic!("{e}"));
    }
    let first_inverse = sequence.pose(0).inverse();
    let mut truth = Vec::with_capacity(sequence.len());
    let mut timestamps = Vec::with_capacity(sequence.len());
    for i in 0..sequence.len() {
        let (timestamp, l, r) = if threaded {
            images(&sequence, i)
        } else {
            cached_images(&sequence, i)
        };
        slam.process(i, timestamp, l.view(), r.view())
            .unwrap_or_else(|e| panic!("frame {i}: {e}"));
        truth.push(first_inverse * sequence.pose(i));
        timestamps.push(timestamp);
    }
    slam.finish().unwrap_or_else(|e| panic!("{e}"));
    let estimate = slam
        .trajectory()
        .unwrap_or_else(|e| panic!("{e}"))
        .iter()
        .map(|(_, p)| p.to_isometry())
        .collect();
    let summary = slam.summary().unwrap_or_else(|e| panic!("{e}"));
    eprintln!("{scene:?}, ORB: {summary:?}");
    let run = SyntheticRun {
        lost: common::untracked(slam.records()),
        estimate,
        truth,
        timestamps,
    };
    (run, slam.records().to_vec())
}

#[test]
fn local_mapping_on_its_own_thread_tracks_and_reports_every_keyframe() {
    let (run, records) = run_orb_slam_with(SceneName::Straight, 80, true);
    let keyframes: Vec<_> = records.iter().filter(|r| r.keyframe).collect();
    let drift = run.final_drift_percent();
    eprintln!(
        "straight street, mapping thread: {} keyframes, final drift {drift:.2} %",
        keyframes.len()
    );
    assert!(run.lost.is_empty(), "frames not tracked: {:?}", run.lost);
    assert!(keyframes.len() > 5);
    // `finish` waited for the thread: every keyframe's mapping is reported.
    for r in &keyframes {
        assert!(
            r.mapping.is_some(),
            "frame {} has no mapping summary",
            r.index
        );
    }
    assert!(drift < 4.0, "final drift {drift:.2} %");
}

#[test]
fn synthetic_straight_street_500_frames_is_tracked_throughout() {
    let run = run_orb_slam(SceneName::Straight);
    // A straight path is collinear, so Umeyama alignment is degenerate
    // (as in evo); both trajectories start at the identity instead.
    let rmse = run.unaligned_rmse();
    let drift = run.final_drift_percent();
    eprintln!(
        "straight street: {:.1} m, position RMSE (unaligned) {rmse:.3} m, final drift {drift:.2} %",
        run.path_length()
    );
    assert!(run.lost.is_empty(), "frames not tracked: {:?}", run.lost);
    // Measured at 2.53 % and 5.76 m (pitch drifts ~0.4° per 100 m: the
    // street has features below the horizon and none above); the bounds
    // catch regressions, the requirement is no loss.
    assert!(drift < 4.0, "final drift {drift:.2} % of the path");
    assert!(rmse < 10.0, "position RMSE {rmse:.3} m");
}

#[test]
fn synthetic_block_loop_500_frames_is_tracked_throughout() {
    let run = run_orb_slam(SceneName::Loop);
    let (truth, estimate) = run.trajectories();
    let report = evaluate(
        &truth,
        &estimate,
        &EvalOptions {
            pairing: Pairing::ByIndex,
            ..EvalOptions::default()
        },
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let drift = run.final_drift_percent();
    eprintln!(
        "block loop: {:.1} m, ATE se3 {:.3} m, final drift {drift:.2} % (no loop closure)",
        run.path_length(),
        report.ate.se3_rmse
    );
    assert!(run.lost.is_empty(), "frames not tracked: {:?}", run.lost);
    assert!(drift < 2.0, "final drift {drift:.2} % of the path");
    assert!(report.ate.se3_rmse < 2.0, "ATE {} m", report.ate.se3_rmse);
}

#[test]
fn tracking_lost_on_blank_frames_recovers_by_relocalisation() {
    let sequence = small_sequence(SceneName::Straight, 60);
    let mut slam = orb_slam(&sequence);
    // Frames 30–32 are blank (a covered lens): no features, tracking is lost.
    let blank = 30..33;
    for i in 0..sequence.len() {
        let (timestamp, mut l, mut r) = images(&sequence, i);
        if blank.contains(&i) {
            let gray = |image: &GrayImage| {
                GrayImage::from_vec(
                    vec![128; image.width() * image.height()],
                    image.width(),
                    image.height(),
                )
                .unwrap_or_else(|e| panic!("{e}"))
            };
            (l, r) = (gray(&l), gray(&r));
        }
        slam.process(i, timestamp, l.view(), r.view())
            .unwrap_or_else(|e| panic!("frame {i}: {e}"));
    }
    let records = slam.records();
    let states: Vec<(usize, TrackingState, spslam::tracking::TrackingMethod)> = records
        .iter()
        .map(|r| (r.index, r.state, r.method))
        .collect();
    for i in blank.clone() {
        assert_eq!(records[i].state, TrackingState::Lost, "blank frame {i}");
    }
    let recovered = records[blank.end..]
        .iter()
        .position(|r| r.method == spslam::tracking::TrackingMethod::Relocalisation)
        .map(|k| blank.end + k);
    eprintln!("relocalised at frame {recovered:?}");
    let Some(recovered) = recovered else {
        panic!("never relocalised: {states:?}");
    };
    assert!(
        recovered <= blank.end + 2,
        "relocalised only at {recovered}"
    );
    // ORB-SLAM3's `Track`: the frame after a relocalisation tracks the
    // reference keyframe (a velocity would span the blank frames).
    assert_eq!(
        records.get(recovered + 1).map(|r| r.method),
        Some(spslam::tracking::TrackingMethod::ReferenceKeyFrame),
        "frame after the relocalisation: {states:?}"
    );
    let lost_after: Vec<usize> = common::untracked(&records[recovered..]);
    assert!(lost_after.is_empty(), "lost again at {lost_after:?}");
    // The relocalised pose is as good as the last one tracked before the
    // blank frames: its error grows by less than 0.1 m across the gap.
    let poses = slam.trajectory().unwrap_or_else(|e| panic!("{e}"));
    let first_inverse = sequence.pose(0).inverse();
    let error = |i: usize| {
        let truth = first_inverse * sequence.pose(i);
        (poses[i].1.translation - truth.translation.vector).norm()
    };
    let (before, after) = (error(blank.start - 1), error(recovered));
    eprintln!("position error {before:.3} m before the gap, {after:.3} m at relocalisation");
    assert!(
        after < before + 0.1,
        "relocalised {after} m off, {before} m before"
    );
}
