//! A whole synthetic sequence: the scene and camera built from a config,
//! and each frame's stereo images (with blur, exposure change and noise),
//! depth map and ground-truth pose.

use std::f64::consts::TAU;

use nalgebra::Isometry3;

use super::camera::StereoCamera;
use super::conditions::Photometry;
use super::config::SyntheticConfig;
use super::error::Result;
use super::render::{render_view, View};
use super::rng::{hash_cell, mix64, unit_from_bits, SplitMix64};
use super::scenes::{build_scene, Scene};
use super::trajectory::Trajectory;
use super::world::World;

/// One rendered stereo frame with its ground truth.
#[derive(Debug, Clone, PartialEq)]
pub struct SyntheticFrame {
    /// Frame index.
    pub index: usize,
    /// Time (seconds).
    pub timestamp: f64,
    /// Ground-truth T_wc of the left camera (at mid-exposure).
    pub pose: Isometry3<f64>,
    /// Image width (pixels).
    pub width: usize,
    /// Image height (pixels).
    pub height: usize,
    /// Left image, 8-bit gray, row-major.
    pub left: Vec<u8>,
    /// Right image, 8-bit gray, row-major.
    pub right: Vec<u8>,
    /// Left camera's depth Z (metres, 0 = sky), row-major; empty when not asked for.
    pub depth: Vec<f32>,
}

/// A configured synthetic sequence; frames are rendered on demand.
#[derive(Debug, Clone)]
pub struct SyntheticSequence {
    config: SyntheticConfig,
    camera: StereoCamera,
    scene: Scene,
}

impl SyntheticSequence {
    /// Checks the config and builds the scene.
    pub fn new(config: SyntheticConfig) -> Result<Self> {
        config.validate()?;
        let camera = StereoCamera::centred(
            config.width,
            config.height,
            config.focal_length,
            config.baseline,
        )
        .with_disparity_offset(config.disparity_offset);
        let scene = build_scene(&config);
        Ok(Self {
            config,
            camera,
            scene,
        })
    }

    /// Replaces the world (e.g. by one with markers at known points),
    /// keeping the camera and the trajectory.
    pub fn with_world(mut self, world: World) -> Self {
        self.scene.world = world;
        self
    }

    /// The config this sequence was built from.
    pub fn config(&self) -> &SyntheticConfig {
        &self.config
    }

    /// The stereo camera.
    pub fn camera(&self) -> &StereoCamera {
        &self.camera
    }

    /// The world.
    pub fn world(&self) -> &World {
        &self.scene.world
    }

    /// The left camera's motion.
    pub fn trajectory(&self) -> &Trajectory {
        &self.scene.trajectory
    }

    /// Number of frames.
    pub fn len(&self) -> usize {
        self.scene.frames
    }

    /// True when the sequence has no frame (never, once built).
    pub fn is_empty(&self) -> bool {
        self.scene.frames == 0
    }

    /// Ground-truth T_wc of the left camera at frame `index`.
    pub fn pose(&self, index: usize) -> Isometry3<f64> {
        self.scene.trajectory.pose(index as f64)
    }

    /// Time of frame `index` (seconds).
    pub fn timestamp(&self, index: usize) -> f64 {
        self.scene.trajectory.time(index)
    }

    /// Renders frame `index`: both images, and the depth map when `with_depth`.
    pub fn render(&self, index: usize, with_depth: bool) -> SyntheticFrame {
        let config = &self.config;
        let samples = config.blur_samples.max(1);
        let sub_poses: Vec<Isometry3<f64>> = (0..samples)
            .map(|k| {
                let offset = if samples == 1 {
                    0.0
                } else {
                    config.shutter * ((k as f64 + 0.5) / samples as f64 - 0.5)
                };
                self.scene.trajectory.pose(index as f64 + offset)
            })
            .collect();
        let depth_with_image = with_depth && samples == 1;
        let left = self.average(&sub_poses, depth_with_image, |p| *p);
        let right = self.average(&sub_poses, false, |p| self.camera.right_pose(p));
        let pose = self.pose(index);
        let depth = if depth_with_image {
            left.depth.clone()
        } else if with_depth {
            render_view(&self.scene.world, &self.camera, &pose, true, config.threads).depth
        } else {
            Vec::new()
        };
        let (gain, offset) = self.exposure(index);
        SyntheticFrame {
            index,
            timestamp: self.timestamp(index),
            pose,
            width: self.camera.width,
            height: self.camera.height,
            left: self.expose(&left.gray, gain, offset, index, 0),
            right: self.expose(&right.gray, gain, offset, index, 1),
            depth,
        }
    }

    /// The mean of the views from the sub-poses (one view without blur).
    fn average(
        &self,
        sub_poses: &[Isometry3<f64>],
        with_depth: bool,
        camera_pose: impl Fn(&Isometry3<f64>) -> Isometry3<f64>,
    ) -> View {
        let threads = self.config.threads;
        let world = &self.scene.world;
        let mut views = sub_poses
            .iter()
            .map(|p| render_view(world, &self.camera, &camera_pose(p), with_depth, threads));
        let Some(mut sum) = views.next() else {
            return render_view(
                world,
                &self.camera,
                &Isometry3::identity(),
                with_depth,
                threads,
            );
        };
        for view in views {
            sum.gray
                .iter_mut()
                .zip(&view.gray)
                .for_each(|(s, g)| *s += g);
        }
        let scale = 1.0 / sub_poses.len() as f32;
        sum.gray.iter_mut().for_each(|s| *s *= scale);
        sum
    }

    /// The frame's exposure: a smooth random gain around 1 and offset
    /// (gray levels), the same for both cameras.
    fn exposure(&self, index: usize) -> (f64, f64) {
        let amplitude = self.config.exposure_variation;
        if amplitude == 0.0 {
            return (1.0, 0.0);
        }
        let t = self.timestamp(index);
        let mut rng = SplitMix64::new(mix64(self.config.seed ^ 0x6578_706f));
        let mut wave = || {
            let (f1, p1) = (rng.uniform(0.05, 0.3), rng.uniform(0.0, TAU));
            let (f2, p2) = (rng.uniform(0.3, 0.8), rng.uniform(0.0, TAU));
            0.7 * (TAU * f1 * t + p1).sin() + 0.3 * (TAU * f2 * t + p2).sin()
        };
        (1.0 + amplitude * wave(), 60.0 * amplitude * wave())
    }

    /// Frames per lap when the path is a loop.
    fn lap_frames(&self) -> Option<usize> {
        let trajectory = &self.scene.trajectory;
        let lap = trajectory.shape.lap_length()?;
        (trajectory.step > 0.0).then(|| (lap / trajectory.step).round() as usize)
    }

    /// Applies gain, offset, the condition's response curve, its noise and
    /// Gaussian pixel noise, then rounds to 8 bits.
    fn expose(&self, gray: &[f32], gain: f64, offset: f64, index: usize, camera: u64) -> Vec<u8> {
        let sigma = self.config.pixel_noise;
        let width = self.camera.width;
        let seed = mix64(self.config.seed ^ 0x006e_6f69_7365);
        let condition_seed = mix64(self.config.seed ^ 0x636f_6e64);
        let photometry = self.config.condition.photometry(
            index,
            self.len(),
            self.lap_frames(),
            self.config.seed,
        );
        let noisy = photometry != Photometry::IDENTITY;
        let layer = (index as u64) << 1 | camera;
        gray.iter()
            .enumerate()
            .map(|(i, &g)| {
                let (x, y) = ((i % width) as i64, (i / width) as i64);
                let mut value = gain * g as f64 + offset;
                if noisy {
                    value = photometry.apply(value);
                    let deviation = photometry.noise_sigma(value);
                    if deviation > 0.0 {
                        value += deviation * gaussian(hash_cell(condition_seed, layer, x, y));
                    }
                }
                if sigma > 0.0 && !photometry.black {
                    value += sigma * gaussian(hash_cell(seed, layer, x, y));
                }
                value.round().clamp(0.0, 255.0) as u8
            })
            .collect()
    }
}

/// A standard normal number from 64 random bits (Box–Muller on two halves).
fn gaussian(bits: u64) -> f64 {
    let u1 = 1.0 - unit_from_bits(bits << 32 | 0x8000_0000); // (0, 1]
    let u2 = unit_from_bits(bits & 0xffff_ffff_0000_0000);
    (-2.0 * u1.ln()).sqrt() * (TAU * u2).cos()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::synthetic::config::SceneName;

    fn small(scene: SceneName) -> SyntheticConfig {
        let mut c = SyntheticConfig::for_scene(scene);
        c.width = 96;
        c.height = 64;
        c.focal_length = 60.0;
        c.frames = Some(3);
        c
    }

    #[test]
    fn noise_has_the_configured_spread() {
        let n = 50_000u64;
        let xs: Vec<f64> = (0..n).map(|i| gaussian(mix64(i))).collect();
        let mean = xs.iter().sum::<f64>() / n as f64;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64;
        assert!(
            mean.abs() < 0.02 && (var - 1.0).abs() < 0.03,
            "{mean} {var}"
        );
    }

    #[test]
    fn frames_are_deterministic_and_noise_changes_them() {
        let seq = SyntheticSequence::new(small(SceneName::Loop)).unwrap();
        let a = seq.render(1, true);
        assert_eq!(a, seq.render(1, true));
        assert_eq!(a.depth.len(), 96 * 64);
        let quiet = SyntheticSequence::new(small(SceneName::Loop).noiseless()).unwrap();
        assert_ne!(a.left, quiet.render(1, false).left);
    }

    #[test]
    fn blur_averages_sub_poses_and_keeps_the_pose() {
        let mut c = small(SceneName::Straight).noiseless();
        c.blur_samples = 4;
        c.shutter = 1.0;
        let blurred = SyntheticSequence::new(c.clone()).unwrap().render(2, true);
        c.blur_samples = 1;
        let sharp = SyntheticSequence::new(c).unwrap().render(2, true);
        assert_eq!(blurred.pose, sharp.pose);
        assert_eq!(blurred.depth, sharp.depth);
        assert_ne!(blurred.left, sharp.left);
    }

    fn mean(image: &[u8]) -> f64 {
        image.iter().map(|&v| v as f64).sum::<f64>() / image.len() as f64
    }

    #[test]
    fn texture_conditions_change_the_facades_and_never_the_ground_truth() {
        use crate::dataset::synthetic::conditions::Condition;
        // Share of horizontal neighbours more than 10 gray levels apart.
        fn edges(image: &[u8], width: usize) -> f64 {
            let steps = image
                .chunks(width)
                .flat_map(|row| row.windows(2))
                .filter(|w| (w[0] as i32 - w[1] as i32).abs() > 10)
                .count();
            steps as f64 / image.len() as f64
        }
        let c = small(SceneName::Loop).noiseless();
        let width = c.width;
        let normal = SyntheticSequence::new(c.clone()).unwrap();
        for condition in [Condition::LowTexture, Condition::RepeatedTexture] {
            let hard = SyntheticSequence::new(SyntheticConfig {
                condition,
                ..c.clone()
            })
            .unwrap();
            for index in [0, normal.len() - 1] {
                let (a, b) = (normal.render(index, true), hard.render(index, true));
                assert_eq!(
                    (a.pose, &a.depth),
                    (b.pose, &b.depth),
                    "{condition} frame {index}"
                );
                assert_ne!(a.left, b.left, "{condition} frame {index}");
                let (before, after) = (edges(&a.left, width), edges(&b.left, width));
                eprintln!("{condition} frame {index}: edge share {before:.4} -> {after:.4}");
                // Measured 0.40–0.47× on frames 0 and 2 (0.183 -> 0.073, 0.163 -> 0.077).
                if condition == Condition::LowTexture {
                    assert!(
                        after < 0.6 * before,
                        "frame {index}: edges {before} -> {after}"
                    );
                }
            }
        }
    }

    #[test]
    fn conditions_change_the_images_and_never_the_ground_truth() {
        use crate::dataset::synthetic::conditions::{Condition, BLACKOUT_FRAMES};
        let mut c = small(SceneName::Loop);
        c.frames = None; // one lap + 1: the second lap starts at the last frame
        let normal = SyntheticSequence::new(c.clone()).unwrap();
        let lap = normal.lap_frames().expect("the loop has laps");
        assert_eq!(normal.len(), lap + 1);
        for condition in [Condition::Dusk, Condition::LowLight, Condition::Blackout] {
            c.condition = condition;
            let hard = SyntheticSequence::new(c.clone()).unwrap();
            for index in [1, normal.len() / 2, lap] {
                let (a, b) = (normal.render(index, true), hard.render(index, true));
                assert_eq!(
                    (a.pose, &a.depth),
                    (b.pose, &b.depth),
                    "{condition} frame {index}"
                );
                let ratio = mean(&b.left) / mean(&a.left);
                let expected = match (condition, index) {
                    (Condition::Dusk, i) if i == lap => 0.2..0.45,
                    (Condition::LowLight, _) => 0.15..0.35,
                    (Condition::Blackout, i) if i == normal.len() / 2 => 0.0..1e-9,
                    _ => 0.999..1.001,
                };
                assert!(
                    expected.contains(&ratio),
                    "{condition} frame {index}: mean ratio {ratio}"
                );
            }
        }
        // The blackout lasts BLACKOUT_FRAMES frames.
        c.condition = Condition::Blackout;
        let kidnap = SyntheticSequence::new(c).unwrap();
        let middle = kidnap.len() / 2;
        assert!(kidnap
            .render(middle + BLACKOUT_FRAMES - 1, false)
            .left
            .iter()
            .all(|&v| v == 0));
        assert!(mean(&kidnap.render(middle + BLACKOUT_FRAMES, false).left) > 20.0);
    }

    #[test]
    fn a_turn_in_place_and_a_jump_back_re_time_the_same_lap() {
        use crate::dataset::synthetic::conditions::Condition;
        use crate::dataset::synthetic::manoeuvre::TURN_IN_PLACE_FRAMES;
        let mut c = small(SceneName::Loop);
        c.frames = None;
        let normal = SyntheticSequence::new(c.clone()).unwrap();
        let (n, middle) = (normal.len(), normal.len() / 2);
        let gap = |a: Isometry3<f64>, b: Isometry3<f64>| {
            let d = a.inverse() * b;
            (d.translation.vector.norm(), d.rotation.angle())
        };

        c.condition = Condition::TurnInPlace;
        let turn = SyntheticSequence::new(c.clone()).unwrap();
        assert_eq!(turn.len(), n + TURN_IN_PLACE_FRAMES);
        for i in [0, middle / 2, middle] {
            assert_eq!(turn.pose(i), normal.pose(i), "frame {i} before the turn");
        }
        let mut turned = 0.0;
        for i in middle + 1..=middle + TURN_IN_PLACE_FRAMES {
            let (moved, angle) = gap(turn.pose(i - 1), turn.pose(i));
            assert!(moved < 1e-9, "frame {i}: stands still, moved {moved} m");
            assert!(angle.to_degrees() < 20.01, "frame {i}: {angle} rad");
            turned += angle;
        }
        assert!((turned.to_degrees() - 360.0).abs() < 1e-6, "{turned}");
        for i in [middle + 1, n - 1] {
            let (moved, angle) = gap(normal.pose(i), turn.pose(i + TURN_IN_PLACE_FRAMES));
            assert!(moved < 1e-9 && angle < 1e-9, "frame {i} after the turn");
        }

        c.condition = Condition::JumpBack;
        let jump = SyntheticSequence::new(c).unwrap();
        let back = n / 4;
        assert_eq!(jump.len(), n + back);
        assert_eq!(jump.pose(middle - 1), normal.pose(middle - 1));
        for i in [middle, n - 1 + back] {
            let (moved, angle) = gap(normal.pose(i - back), jump.pose(i));
            assert!(moved < 1e-9 && angle < 1e-9, "frame {i} after the jump");
        }
        // The jump is a kidnap: far from where the camera was.
        let (moved, _) = gap(jump.pose(middle - 1), jump.pose(middle));
        assert!(moved > 30.0, "the jump moves {moved} m");
        // The ground truth still ends where the lap does.
        assert!(gap(jump.pose(jump.len() - 1), Isometry3::identity()).0 < 1e-9);
    }
}
