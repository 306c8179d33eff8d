//! One synthetic sequence run through each sensor (ORB, local mapping
//! inline): stereo, RGB-D with realistic depth noise, or monocular. The
//! estimate and the exact ground truth come back as `T_wc` relative to
//! the first frame, with the records.

use nalgebra::Isometry3;
use spslam::camera::{CameraRig, DepthImage, Sensor};
use spslam::dataset::synthetic::{SyntheticFrame, SyntheticSequence};
use spslam::eval::Trajectory;
use spslam::features::{GrayImage, OrbConfig, OrbExtractor};
use spslam::settings::SlamSettings;
use spslam::system::{FrameRecord, SlamSystem};
use spslam::tracking::{Frontend, SensorImages, TrackingState};

use super::rng::Rng;

/// The depth noise of a structured-light RGB-D camera.
#[derive(Debug, Clone, Copy)]
pub struct DepthNoise {
    /// Share of pixels with no depth, at random.
    pub missing: f64,
    /// Gaussian axial noise σ(z) = a + b·(z − 0.4)² (Nguyen et al. 2012,
    /// Kinect: a = 0.0012, b = 0.0019), metres.
    pub sigma_a: f64,
    /// See `sigma_a`.
    pub sigma_b: f64,
    /// Quantisation step, metres (TUM's 16-bit PNGs: 1/5000).
    pub step: f64,
    /// Farthest depth measured (16 bits at 5000 per metre: 13.1 m).
    pub max_depth: f64,
}

impl DepthNoise {
    /// A Kinect-like camera stored as TUM does: 1/5000 m steps, 10 % of
    /// the pixels missing, Nguyen's axial noise, 13.1 m at most.
    pub const KINECT_TUM: Self = Self {
        missing: 0.10,
        sigma_a: 0.0012,
        sigma_b: 0.0019,
        step: 1.0 / 5000.0,
        max_depth: 65535.0 / 5000.0,
    };

    /// The rendered depth with this noise.
    pub fn apply(&self, frame: &SyntheticFrame, rng: &mut Rng) -> DepthImage {
        let metres = frame
            .depth
            .iter()
            .map(|&z| {
                let z = f64::from(z);
                if z <= 0.0 || rng.uniform() < self.missing {
                    return 0.0;
                }
                let sigma = self.sigma_a + self.sigma_b * (z - 0.4).powi(2);
                let noisy = ((z + sigma * rng.normal()) / self.step).round() * self.step;
                if noisy > self.max_depth || noisy <= 0.0 {
                    0.0
                } else {
                    noisy as f32
                }
            })
            .collect();
        DepthImage::from_metres(metres, frame.width, frame.height).unwrap_or_else(|e| panic!("{e}"))
    }
}

/// A run of one sensor over a sequence.
pub struct SensorRun {
    /// Per frame: the record.
    pub records: Vec<FrameRecord>,
    /// `T_wc` estimates relative to the first frame.
    pub estimate: Vec<Isometry3<f64>>,
    /// Ground truth, relative to the first frame.
    pub truth: Vec<Isometry3<f64>>,
    /// Timestamps.
    pub timestamps: Vec<f64>,
}

impl SensorRun {
    /// Ground truth and estimate as trajectories.
    pub fn trajectories(&self) -> (Trajectory, Trajectory) {
        (
            Trajectory::new(self.timestamps.clone(), self.truth.clone()),
            Trajectory::new(self.timestamps.clone(), self.estimate.clone()),
        )
    }

    /// Frames from `first` on that were not tracked.
    pub fn lost_from(&self, first: usize) -> Vec<usize> {
        self.records
            .iter()
            .filter(|r| r.index >= first && r.state != TrackingState::Ok)
            .map(|r| r.index)
            .collect()
    }

    /// Ground truth and estimate from frame `first` on.
    pub fn trajectories_from(&self, first: usize) -> (Trajectory, Trajectory) {
        let keep: Vec<usize> = (first..self.truth.len()).collect();
        let (truth, estimate) = self.trajectories();
        (truth.select(&keep), estimate.select(&keep))
    }

    /// Path length of the ground truth, metres.
    pub fn path_length(&self) -> f64 {
        self.truth
            .windows(2)
            .map(|w| (w[1].translation.vector - w[0].translation.vector).norm())
            .sum()
    }
}

/// The sequence's rig for `sensor` with default settings.
pub fn rig_for(sequence: &SyntheticSequence, sensor: Sensor) -> CameraRig {
    let cam = *sequence.camera();
    let settings = SlamSettings::rectified_stereo(cam.fx, cam.fy, cam.cx, cam.cy, cam.baseline);
    CameraRig::for_sensor(&settings, sensor, cam.width, cam.height)
        .unwrap_or_else(|e| panic!("{e}"))
}

/// An ORB system for `sensor`, mapping inline, invariants checked.
pub fn orb_system(sequence: &SyntheticSequence, sensor: Sensor) -> SlamSystem {
    let rig = rig_for(sequence, sensor);
    let orb =
        || Box::new(OrbExtractor::new(OrbConfig::default()).unwrap_or_else(|e| panic!("{e}")));
    let frontend = match sensor {
        Sensor::Stereo => Frontend::new(orb(), orb(), &rig),
        _ => Frontend::single(orb(), &rig).unwrap_or_else(|e| panic!("{e}")),
    };
    let mut slam = SlamSystem::new(rig, frontend);
    if let Some(mapper) = slam.mapper_mut() {
        mapper.check_invariants = true;
    }
    slam
}

/// Runs every frame of `sequence` through `slam` as `sensor` (RGB-D with
/// `noise` on the rendered depth, seeded by `seed`).
pub fn run_sensor(
    sequence: &SyntheticSequence,
    slam: &mut SlamSystem,
    sensor: Sensor,
    noise: DepthNoise,
    seed: u64,
) -> SensorRun {
    let mut rng = Rng::new(seed);
    let first_inverse = sequence.pose(0).inverse();
    let (mut truth, mut timestamps) = (Vec::new(), Vec::new());
    for i in 0..sequence.len() {
        let frame = super::synthetic_slam::rendered(sequence, i, sensor == Sensor::Rgbd);
        let image = |data: &[u8]| {
            GrayImage::from_vec(data.to_vec(), frame.width, frame.height)
                .unwrap_or_else(|e| panic!("{e}"))
        };
        let (left, right) = (image(&frame.left), image(&frame.right));
        let depth = (sensor == Sensor::Rgbd).then(|| noise.apply(&frame, &mut rng));
        let images = match (&depth, sensor) {
            (Some(depth), _) => SensorImages::Rgbd {
                image: left.view(),
                depth,
            },
            (None, Sensor::Monocular) => SensorImages::Monocular(left.view()),
            (None, _) => SensorImages::Stereo {
                left: left.view(),
                right: right.view(),
            },
        };
        slam.process_images(i, frame.timestamp, images)
            .unwrap_or_else(|e| panic!("frame {i}: {e}"));
        truth.push(first_inverse * sequence.pose(i));
        timestamps.push(frame.timestamp);
    }
    slam.finish().unwrap_or_else(|e| panic!("{e}"));
    let estimate = slam
        .trajectory()
        .unwrap_or_else(|e| panic!("{e}"))
        .iter()
        .map(|(_, p)| p.to_isometry())
        .collect();
    SensorRun {
        records: slam.records().to_vec(),
        estimate,
        truth,
        timestamps,
    }
}
