//! Camera paths: a straight drive, a lap of a rounded rectangle that ends
//! exactly where it starts, and a smooth random hand-held shake on top.
//!
//! Poses are T_wc of the left camera in the KITTI convention (x right,
//! y down, z forward). Every path starts at the identity, heading +z.

use std::f64::consts::{FRAC_PI_2, TAU};

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use super::manoeuvre::Manoeuvre;
use super::rng::SplitMix64;

/// The centre line the camera follows, on the plane y = 0.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PathShape {
    /// Straight ahead along +z.
    Straight,
    /// A rectangle with rounded corners in x ∈ [0, width], z ∈ [−length/2,
    /// length/2], driven clockwise seen from above (turning right), from the
    /// middle of its x = 0 side.
    RoundedRectangle {
        /// Extent along x (metres).
        width: f64,
        /// Extent along z (metres).
        length: f64,
        /// Corner radius (metres).
        radius: f64,
    },
}

/// Small smooth random rotations and translations (a hand-held camera):
/// each axis is a sum of three sines with random frequencies in
/// 0.15–1.2 Hz, zero at the start.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Wobble {
    /// Peak-ish rotation about each axis (radians).
    pub rotation: f64,
    /// Peak-ish offset along each axis (metres).
    pub translation: f64,
    /// Seed of the frequencies and phases.
    pub seed: u64,
}

/// A path, how fast it is followed, and an optional shake.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Trajectory {
    /// The centre line.
    pub shape: PathShape,
    /// Distance covered between two frames (metres).
    pub step: f64,
    /// Frames per second (times and the shake's frequencies).
    pub fps: f64,
    /// Hand-held shake, when set.
    pub wobble: Option<Wobble>,
    /// A turn in place or a jump back, when set.
    pub manoeuvre: Option<Manoeuvre>,
}

impl PathShape {
    /// The length of one lap (`None` for an open path).
    pub fn lap_length(&self) -> Option<f64> {
        match *self {
            PathShape::Straight => None,
            PathShape::RoundedRectangle {
                width,
                length,
                radius,
            } => Some(2.0 * (width - 2.0 * radius) + 2.0 * (length - 2.0 * radius) + TAU * radius),
        }
    }

    /// Position `(x, z)` and heading (radians, 0 = +z, π/2 = +x) at arc length `s`.
    pub fn at(&self, s: f64) -> ([f64; 2], f64) {
        match *self {
            PathShape::Straight => ([0.0, s], 0.0),
            PathShape::RoundedRectangle {
                width,
                length,
                radius,
            } => {
                let lap = self.lap_length().unwrap_or(f64::INFINITY);
                rounded_rectangle_at(s.rem_euclid(lap), width, length, radius)
            }
        }
    }
}

/// Walks the segments of the rounded rectangle: half a side, then
/// (arc, side) four times with the last side cut in half.
fn rounded_rectangle_at(mut s: f64, width: f64, length: f64, radius: f64) -> ([f64; 2], f64) {
    let sides = [
        0.5 * (length - 2.0 * radius),
        width - 2.0 * radius,
        length - 2.0 * radius,
        width - 2.0 * radius,
        0.5 * (length - 2.0 * radius),
    ];
    let arc = FRAC_PI_2 * radius;
    let (mut x, mut z, mut heading) = (0.0, 0.0, 0.0f64);
    for (i, side) in sides.iter().enumerate() {
        let (fx, fz) = (heading.sin(), heading.cos());
        if s <= *side || i == sides.len() - 1 {
            return ([x + fx * s, z + fz * s], heading);
        }
        s -= side;
        x += fx * side;
        z += fz * side;
        // Turning right: the centre lies `radius` to the right.
        let (cx, cz) = (x + radius * heading.cos(), z - radius * heading.sin());
        let turn = s.min(arc) / radius;
        let h = heading + turn;
        let (px, pz) = (cx - radius * h.cos(), cz + radius * h.sin());
        if s <= arc {
            return ([px, pz], h);
        }
        s -= arc;
        heading += FRAC_PI_2;
        (x, z) = (px, pz);
    }
    ([x, z], heading)
}

impl Wobble {
    /// Rotation angles (about x, y, z) and offsets (camera frame) at time `t`.
    fn at(&self, t: f64) -> ([f64; 3], [f64; 3]) {
        let mut rng = SplitMix64::new(self.seed ^ 0x0077_6f62_626c_0065);
        let mut channel = |amplitude: f64| {
            let mut sum = 0.0;
            for k in 0..3 {
                let frequency = rng.uniform(0.15, 1.2);
                let phase = rng.uniform(0.0, TAU);
                let weight = amplitude / (k as f64 + 1.5);
                sum += weight * ((TAU * frequency * t + phase).sin() - phase.sin());
            }
            sum
        };
        let angles = [
            channel(self.rotation),
            channel(self.rotation),
            channel(self.rotation),
        ];
        let offsets = [
            channel(self.translation),
            channel(self.translation),
            channel(self.translation),
        ];
        (angles, offsets)
    }
}

impl Trajectory {
    /// The left camera's T_wc at frame `frame` (fractional frames are the
    /// poses in between, used for motion blur).
    pub fn pose(&self, frame: f64) -> Isometry3<f64> {
        let (path_frame, turn) = self.manoeuvre.map_or((frame, 0.0), |m| m.warp(frame));
        let ([x, z], heading) = self.shape.at(path_frame * self.step);
        let yaw = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), heading + turn);
        let mut rotation = yaw;
        let mut position = Vector3::new(x, 0.0, z);
        if let Some(wobble) = &self.wobble {
            let (angles, offsets) = wobble.at(frame / self.fps);
            rotation = yaw * UnitQuaternion::from_euler_angles(angles[0], angles[1], angles[2]);
            position += yaw * Vector3::new(offsets[0], offsets[1], offsets[2]);
        }
        Isometry3::from_parts(Translation3::from(position), rotation)
    }

    /// Time of frame `frame` (seconds).
    pub fn time(&self, frame: usize) -> f64 {
        frame as f64 / self.fps
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ring(step: f64) -> Trajectory {
        Trajectory {
            shape: PathShape::RoundedRectangle {
                width: 70.0,
                length: 50.0,
                radius: 5.0,
            },
            step,
            fps: 10.0,
            wobble: None,
            manoeuvre: None,
        }
    }

    #[test]
    fn every_path_starts_at_the_identity() {
        let wobble = Some(Wobble {
            rotation: 0.05,
            translation: 0.05,
            seed: 4,
        });
        for mut t in [
            ring(1.0),
            Trajectory {
                shape: PathShape::Straight,
                ..ring(1.0)
            },
        ] {
            assert!((t.pose(0.0).to_homogeneous() - nalgebra::Matrix4::identity()).norm() < 1e-15);
            t.wobble = wobble;
            assert!((t.pose(0.0).to_homogeneous() - nalgebra::Matrix4::identity()).norm() < 1e-15);
        }
    }

    #[test]
    fn a_lap_closes_exactly() {
        let shape = ring(1.0).shape;
        let lap = shape.lap_length().unwrap();
        let frames = (lap / 1.0).round();
        let t = ring(lap / frames);
        let end = t.pose(frames);
        let error = (end.to_homogeneous() - Isometry3::identity().to_homogeneous()).norm();
        assert!(error < 1e-9, "closure error {error}");
    }

    #[test]
    fn the_path_is_continuous_with_unit_speed_and_turns_right() {
        let shape = ring(1.0).shape;
        let lap = shape.lap_length().unwrap();
        let n = 20_000;
        let ds = lap / n as f64;
        let mut previous = shape.at(0.0);
        for i in 1..n {
            let current = shape.at(i as f64 * ds);
            let dx = current.0[0] - previous.0[0];
            let dz = current.0[1] - previous.0[1];
            let speed = (dx * dx + dz * dz).sqrt() / ds;
            assert!(
                (speed - 1.0).abs() < 1e-3,
                "speed {speed} at s = {}",
                i as f64 * ds
            );
            assert!(current.1 >= previous.1 - 1e-12, "heading must not decrease");
            previous = current;
        }
        // Corners: the far corner of the ring.
        let ([x, z], heading) = shape.at(lap / 2.0);
        assert!((x - 70.0).abs() < 1e-9 && z.abs() < 1e-9, "{x} {z}");
        assert!((heading - std::f64::consts::PI).abs() < 1e-12);
    }

    #[test]
    fn the_shake_is_small_and_smooth() {
        let mut t = Trajectory {
            shape: PathShape::Straight,
            ..ring(0.06)
        };
        t.fps = 20.0;
        t.wobble = Some(Wobble {
            rotation: 0.03,
            translation: 0.03,
            seed: 1,
        });
        let mut previous = t.pose(0.0);
        for i in 1..400 {
            let pose = t.pose(i as f64);
            let delta = previous.inverse() * pose;
            assert!(delta.rotation.angle() < 0.02, "frame {i}");
            assert!(
                (delta.translation.vector.norm() - 0.06).abs() < 0.03,
                "frame {i}"
            );
            let lateral = pose.translation.vector.x.abs() + pose.translation.vector.y.abs();
            assert!(lateral < 0.2, "frame {i}: {lateral}");
            previous = pose;
        }
    }
}
