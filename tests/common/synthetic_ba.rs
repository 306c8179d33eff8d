//! Seeded synthetic bundle-adjustment scenes for the optimisation tests and
//! benchmarks: a KITTI-like stereo camera moving forward, points seen by
//! 3–6 consecutive keyframes, pixel noise scaled by the octave (so the
//! information `1/σ²(octave)` is exact), optional gross outliers.
#![allow(dead_code)]

pub use super::rng::Rng;
use nalgebra::{UnitQuaternion, Vector3, Vector6};
use spslam::optim::local_ba::{BaObservation, BundleProblem};
use spslam::optim::pose_only::PoseCorrespondence;
use spslam::optim::reprojection::{inv_level_sigma2, Observation, PinholeStereo};
use spslam::optim::{LieGroup, Se3};

/// KITTI 00's rectified camera (fx, fy, cx, cy, bf).
pub fn kitti_camera() -> PinholeStereo {
    PinholeStereo::new(718.856, 718.856, 607.1928, 185.2157, 386.1448)
}

/// ORB-SLAM3's scale factor between octaves.
pub const SCALE_FACTOR: f64 = 1.2;

/// How to build a scene.
#[derive(Debug, Clone, Copy)]
pub struct SceneSpec {
    /// Number of keyframes.
    pub keyframes: usize,
    /// Number of points.
    pub points: usize,
    /// Fraction of observations that are stereo (0 = mono only, 1 = stereo only).
    pub stereo_fraction: f64,
    /// Pixel noise σ at octave 0 (scaled by 1.2^octave).
    pub pixel_noise: f64,
    /// Fraction of observations replaced by gross outliers.
    pub outlier_fraction: f64,
    /// Highest octave used (0..=max_octave).
    pub max_octave: u32,
    /// Seed.
    pub seed: u64,
}

impl Default for SceneSpec {
    fn default() -> Self {
        Self {
            keyframes: 10,
            points: 500,
            stereo_fraction: 0.5,
            pixel_noise: 0.7,
            outlier_fraction: 0.0,
            max_octave: 3,
            seed: 1,
        }
    }
}

/// A scene with ground truth, noisy observations and which are outliers.
pub struct Scene {
    /// The camera.
    pub camera: PinholeStereo,
    /// Ground-truth `T_cw`.
    pub poses: Vec<Se3>,
    /// Ground-truth points.
    pub points: Vec<Vector3<f64>>,
    /// Noisy observations.
    pub observations: Vec<BaObservation>,
    /// Per observation: true for a planted gross outlier.
    pub is_outlier: Vec<bool>,
}

/// The keyframe trajectory: forward along z, 0.8 m apart, a gentle yaw and sway.
fn keyframe_pose(k: usize) -> Se3 {
    let s = k as f64;
    let centre = Vector3::new(0.3 * (0.4 * s).sin(), 0.05 * (0.7 * s).cos(), 0.8 * s);
    let r_wc = UnitQuaternion::from_euler_angles(0.01 * (0.3 * s).sin(), 0.02 * s, 0.0);
    // T_cw = (T_wc)⁻¹
    Se3::new(r_wc, centre).inverse()
}

/// An observation of `point` from `pose` with octave noise (and maybe an outlier offset).
fn observe(
    rng: &mut Rng,
    camera: &PinholeStereo,
    pose: &Se3,
    point: &Vector3<f64>,
    spec: &SceneSpec,
    outlier: bool,
) -> Observation {
    let octave = rng.int(0, spec.max_octave as usize) as u32;
    let information = inv_level_sigma2(SCALE_FACTOR, octave);
    let sigma = spec.pixel_noise / information.sqrt();
    let p_cam = pose.transform_point(point);
    let mut m = camera.project_stereo(&p_cam);
    m.x += sigma * rng.normal();
    m.y += sigma * rng.normal();
    m.z += sigma * rng.normal();
    if outlier {
        let magnitude = rng.range(20.0, 100.0);
        let angle = rng.range(0.0, std::f64::consts::TAU);
        let (du, dv) = (magnitude * angle.cos(), magnitude * angle.sin());
        m.x += du;
        m.y += dv;
        m.z += du;
    }
    if rng.uniform() < spec.stereo_fraction {
        Observation::stereo(m.x, m.y, m.z, information)
    } else {
        Observation::mono(m.x, m.y, information)
    }
}

impl Scene {
    /// Builds a scene: each point is placed in front of a reference keyframe
    /// (pixel inside a 1241×376 image, depth 4–30 m) and seen by it and the
    /// 2–5 keyframes before it (further back along the forward motion, so
    /// deeper and nearer the image centre).
    pub fn new(spec: &SceneSpec) -> Self {
        let mut rng = Rng::new(spec.seed);
        let camera = kitti_camera();
        let poses: Vec<Se3> = (0..spec.keyframes).map(keyframe_pose).collect();
        let mut points = Vec::with_capacity(spec.points);
        let mut observations = Vec::new();
        let mut is_outlier = Vec::new();
        for index in 0..spec.points {
            let seen_by = rng.int(3, 6).min(spec.keyframes);
            let first = rng.int(0, spec.keyframes - seen_by);
            let reference = &poses[first + seen_by - 1];
            let (u, v, z) = (
                rng.range(0.0, 1241.0),
                rng.range(0.0, 376.0),
                rng.range(4.0, 30.0),
            );
            let p_cam = Vector3::new(
                (u - camera.cx) / camera.fx * z,
                (v - camera.cy) / camera.fy * z,
                z,
            );
            let point = reference.inverse().transform_point(&p_cam);
            points.push(point);
            for (pose, camera_pose) in poses.iter().enumerate().skip(first).take(seen_by) {
                let outlier = rng.uniform() < spec.outlier_fraction;
                let obs = observe(&mut rng, &camera, camera_pose, &point, spec, outlier);
                observations.push(BaObservation {
                    pose,
                    point: index,
                    obs,
                });
                is_outlier.push(outlier);
            }
        }
        Self {
            camera,
            poses,
            points,
            observations,
            is_outlier,
        }
    }

    /// The problem with free poses perturbed (rotation σ `rot_deg`° per axis,
    /// translation σ `trans_m` per axis), points perturbed by σ `point_m`;
    /// poses in `fixed` keep their ground truth.
    pub fn noisy_problem(
        &self,
        fixed: &[usize],
        rot_deg: f64,
        trans_m: f64,
        point_m: f64,
        seed: u64,
    ) -> BundleProblem {
        let mut rng = Rng::new(seed ^ 0xA5A5_5A5A);
        let mut flags = vec![false; self.poses.len()];
        for &f in fixed {
            flags[f] = true;
        }
        let poses = self
            .poses
            .iter()
            .zip(&flags)
            .map(|(pose, &is_fixed)| {
                if is_fixed {
                    *pose
                } else {
                    perturb(&mut rng, pose, rot_deg, trans_m)
                }
            })
            .collect();
        let points = self
            .points
            .iter()
            .map(|p| p + rng.normal3(point_m))
            .collect();
        BundleProblem {
            camera: self.camera,
            poses,
            fixed: flags,
            points,
            observations: self.observations.clone(),
        }
    }

    /// The observations of keyframe `pose` as pose-only correspondences with
    /// ground-truth points, and whether each is a planted outlier.
    pub fn correspondences(&self, pose: usize) -> (Vec<PoseCorrespondence>, Vec<bool>) {
        self.observations
            .iter()
            .zip(&self.is_outlier)
            .filter(|(o, _)| o.pose == pose)
            .map(|(o, &out)| {
                (
                    PoseCorrespondence {
                        point: self.points[o.point],
                        observation: o.obs,
                    },
                    out,
                )
            })
            .unzip()
    }
}

/// `exp(δ)·pose` with δ's rotation σ `rot_deg`° and translation σ `trans_m` per axis.
pub fn perturb(rng: &mut Rng, pose: &Se3, rot_deg: f64, trans_m: f64) -> Se3 {
    let w = rng.normal3(rot_deg.to_radians());
    let t = rng.normal3(trans_m);
    pose.perturb_left(&Vector6::new(w.x, w.y, w.z, t.x, t.y, t.z))
}

/// Rotation (degrees) and translation (metres) difference of two `T_cw`,
/// compared as camera centres and orientations.
pub fn pose_error(a: &Se3, b: &Se3) -> (f64, f64) {
    let rot = a.rotation.angle_to(&b.rotation).to_degrees();
    let ca = a.inverse().translation;
    let cb = b.inverse().translation;
    (rot, (ca - cb).norm())
}

/// A long chain of keyframes moving forward 0.8 m apart with a heading that
/// oscillates (±0.1 rad) instead of turning round, so every point stays in
/// front of the 3–5 consecutive keyframes that see it; `points_per_keyframe`
/// points per keyframe, 0.5 px × 1.2^octave noise, half stereo (global-BA
/// sized problems for the sparse reduced camera system's test and bench).
pub fn chain_scene(keyframes: usize, points_per_keyframe: usize, seed: u64) -> Scene {
    let mut rng = Rng::new(seed);
    let camera = kitti_camera();
    let poses: Vec<Se3> = (0..keyframes)
        .map(|k| {
            let s = k as f64;
            let centre = Vector3::new(0.3 * (0.4 * s).sin(), 0.05 * (0.7 * s).cos(), 0.8 * s);
            let r_wc = UnitQuaternion::from_euler_angles(
                0.01 * (0.3 * s).sin(),
                0.1 * (0.05 * s).sin(),
                0.0,
            );
            Se3::new(r_wc, centre).inverse()
        })
        .collect();
    let n_points = keyframes * points_per_keyframe;
    let mut points = Vec::with_capacity(n_points);
    let mut observations = Vec::new();
    for index in 0..n_points {
        let seen_by = rng.int(3, 5).min(keyframes);
        let first = rng.int(0, keyframes - seen_by);
        let reference = &poses[first + seen_by - 1];
        let (u, v, z) = (
            rng.range(0.0, 1241.0),
            rng.range(0.0, 376.0),
            rng.range(4.0, 30.0),
        );
        let p_cam = Vector3::new(
            (u - camera.cx) / camera.fx * z,
            (v - camera.cy) / camera.fy * z,
            z,
        );
        let point = reference.inverse().transform_point(&p_cam);
        points.push(point);
        for (pose, camera_pose) in poses.iter().enumerate().skip(first).take(seen_by) {
            let octave = rng.int(0, 3) as u32;
            let information = inv_level_sigma2(SCALE_FACTOR, octave);
            let sigma = 0.5 / information.sqrt();
            let mut m = camera.project_stereo(&camera_pose.transform_point(&point));
            m.x += sigma * rng.normal();
            m.y += sigma * rng.normal();
            m.z += sigma * rng.normal();
            let obs = if rng.uniform() < 0.5 {
                Observation::stereo(m.x, m.y, m.z, information)
            } else {
                Observation::mono(m.x, m.y, information)
            };
            observations.push(BaObservation {
                pose,
                point: index,
                obs,
            });
        }
    }
    let is_outlier = vec![false; observations.len()];
    Scene {
        camera,
        poses,
        points,
        observations,
        is_outlier,
    }
}
