//! The built-in scenes: a city block (driven around), a straight street,
//! and a ring corridor (walked with a hand-held camera).

use nalgebra::{Point3, Vector3};

use super::config::{SceneName, SyntheticConfig};
use super::rng::mix64;
use super::styles;
use super::trajectory::{PathShape, Trajectory, Wobble};
use super::world::{Plane, Skyline, World};

/// Camera height above the road (KITTI's, metres).
const CAR_CAMERA_HEIGHT: f64 = 1.65;
/// Camera height above the floor for the walker (metres).
const WALKER_CAMERA_HEIGHT: f64 = 1.5;
/// Frames of the open-path scenes when the config does not say.
const DEFAULT_OPEN_FRAMES: usize = 200;

/// A world and the path through it.
#[derive(Debug, Clone)]
pub struct Scene {
    /// The surfaces.
    pub world: World,
    /// The left camera's motion.
    pub trajectory: Trajectory,
    /// Number of frames to render.
    pub frames: usize,
}

/// Builds the scene the config names.
pub fn build_scene(config: &SyntheticConfig) -> Scene {
    let nominal_step = config.speed / config.fps;
    match config.scene {
        SceneName::Loop => block_ring(config, nominal_step),
        SceneName::Straight => straight_street(config, nominal_step),
        SceneName::Wobbly => ring_corridor(config, nominal_step),
    }
}

/// A rounded-rectangle path `offset` metres outside an inner rectangle,
/// with the step rounded so a lap is a whole number of frames.
fn ring_path(inner_half: [f64; 2], offset: f64, nominal_step: f64) -> (PathShape, f64, usize) {
    let shape = PathShape::RoundedRectangle {
        width: 2.0 * (inner_half[0] + offset),
        length: 2.0 * (inner_half[1] + offset),
        radius: offset,
    };
    let lap = shape.lap_length().unwrap_or(0.0);
    let frames_per_lap = (lap / nominal_step).round().max(1.0) as usize;
    (shape, lap / frames_per_lap as f64, frames_per_lap)
}

/// The four walls of the rectangle x ∈ [x0, x1], z ∈ [z0, z1], facing
/// outwards (or inwards), each made by `make(from, to, index)`.
fn rectangle_walls(
    [x0, x1]: [f64; 2],
    [z0, z1]: [f64; 2],
    outwards: bool,
    mut make: impl FnMut([f64; 2], [f64; 2], u64) -> Plane,
) -> Vec<Plane> {
    let mut corners = [[x0, z1], [x0, z0], [x1, z0], [x1, z1]];
    if !outwards {
        corners.reverse();
    }
    (0..4)
        .map(|i| make(corners[i], corners[(i + 1) % 4], i as u64))
        .collect()
}

/// A horizontal plane at height `y` over x ∈ [x0, x1], z ∈ [z0, z1],
/// facing up (a floor) or down (a ceiling).
fn horizontal(
    y: f64,
    [x0, x1]: [f64; 2],
    [z0, z1]: [f64; 2],
    up: bool,
    texture: super::Texture,
) -> Plane {
    let (origin, v_axis) = if up {
        (Point3::new(x0, y, z0), Vector3::z())
    } else {
        (Point3::new(x0, y, z1), -Vector3::z())
    };
    Plane::new(origin, Vector3::x(), v_axis, x1 - x0, z1 - z0, texture)
}

/// The `loop` scene: a 60 m × 40 m block; the car drives 5 m from its
/// façades, the opposite façades are 14 m away; one lap ≈ 231 m.
fn block_ring(config: &SyntheticConfig, nominal_step: f64) -> Scene {
    let seed = config.seed;
    let (half_x, half_z, offset, street) = (30.0, 20.0, 5.0, 14.0);
    let (shape, step, frames_per_lap) = ring_path([half_x, half_z], offset, nominal_step);
    // The path's x = 0 side runs along the block's west side at x = offset.
    let centre_x = half_x + offset;
    let inner_x = [centre_x - half_x, centre_x + half_x];
    let outer_x = [inner_x[0] - street, inner_x[1] + street];
    let (inner_z, outer_z) = ([-half_z, half_z], [-half_z - street, half_z + street]);
    let ground = CAR_CAMERA_HEIGHT;
    let mut planes = rectangle_walls(inner_x, inner_z, true, |a, b, i| {
        building_row(a, b, ground, mix64(seed ^ (10 + i)), 0.0)
    });
    planes.extend(rectangle_walls(outer_x, outer_z, false, |a, b, i| {
        building_row(a, b, ground, mix64(seed ^ (20 + i)), 0.25)
    }));
    let margin = 40.0;
    planes.push(horizontal(
        ground,
        [outer_x[0] - margin, outer_x[1] + margin],
        [outer_z[0] - margin, outer_z[1] + margin],
        true,
        styles::asphalt(mix64(seed ^ 30)),
    ));
    Scene {
        world: World::new(planes),
        trajectory: Trajectory {
            shape,
            step,
            fps: config.fps,
            wobble: None,
        },
        frames: config.frames.unwrap_or(frames_per_lap + 1),
    }
}

/// A row of façades of different heights from `from` to `to`.
fn building_row(from: [f64; 2], to: [f64; 2], ground: f64, seed: u64, gaps: f64) -> Plane {
    Plane::wall(from, to, ground, 0.0, styles::facade(seed)).with_skyline(Skyline {
        segment: 12.0,
        min_height: 7.0,
        max_height: 22.0,
        gap_probability: gaps,
        seed,
    })
}

/// The `straight` scene: a street 14 m wide, buildings on both sides with
/// side-street gaps, a wall far ahead.
fn straight_street(config: &SyntheticConfig, step: f64) -> Scene {
    let seed = config.seed;
    let frames = config.frames.unwrap_or(DEFAULT_OPEN_FRAMES);
    let far = frames as f64 * step + 80.0;
    let ground = CAR_CAMERA_HEIGHT;
    let (left_x, right_x, back) = (-8.0, 6.0, -30.0);
    let planes = vec![
        building_row([left_x, back], [left_x, far], ground, mix64(seed ^ 40), 0.3),
        building_row(
            [right_x, far],
            [right_x, back],
            ground,
            mix64(seed ^ 41),
            0.3,
        ),
        Plane::wall(
            [-60.0, far],
            [60.0, far],
            ground,
            30.0,
            styles::facade(mix64(seed ^ 42)),
        ),
        horizontal(
            ground,
            [-60.0, 60.0],
            [back, far],
            true,
            styles::asphalt(mix64(seed ^ 43)),
        ),
    ];
    Scene {
        world: World::new(planes),
        trajectory: Trajectory {
            shape: PathShape::Straight,
            step,
            fps: config.fps,
            wobble: None,
        },
        frames,
    }
}

/// The `wobbly` scene: a ring corridor 3 m wide and 2.8 m high around a
/// 11 m × 7 m core, walked 1.5 m from the inner wall with a hand-held shake.
fn ring_corridor(config: &SyntheticConfig, nominal_step: f64) -> Scene {
    let seed = config.seed;
    let (half_x, half_z, offset, width, height) = (5.5, 3.5, 1.5, 3.0, 2.8);
    let (shape, step, _) = ring_path([half_x, half_z], offset, nominal_step);
    let centre_x = half_x + offset;
    let inner_x = [centre_x - half_x, centre_x + half_x];
    let outer_x = [inner_x[0] - width, inner_x[1] + width];
    let (inner_z, outer_z) = ([-half_z, half_z], [-half_z - width, half_z + width]);
    let floor = WALKER_CAMERA_HEIGHT;
    let ceiling = floor - height;
    let wall = |a, b, i: u64| {
        Plane::wall(
            a,
            b,
            floor,
            height,
            styles::indoor_wall(mix64(seed ^ (50 + i))),
        )
    };
    let mut planes = rectangle_walls(inner_x, inner_z, true, wall);
    planes.extend(rectangle_walls(outer_x, outer_z, false, |a, b, i| {
        wall(a, b, 4 + i)
    }));
    planes.push(horizontal(
        floor,
        outer_x,
        outer_z,
        true,
        styles::floor_tiles(mix64(seed ^ 60)),
    ));
    planes.push(horizontal(
        ceiling,
        outer_x,
        outer_z,
        false,
        styles::ceiling(mix64(seed ^ 61)),
    ));
    Scene {
        world: World::new(planes),
        trajectory: Trajectory {
            shape,
            step,
            fps: config.fps,
            wobble: Some(Wobble {
                rotation: 0.04,
                translation: 0.03,
                seed: mix64(seed ^ 70),
            }),
        },
        frames: config.frames.unwrap_or(DEFAULT_OPEN_FRAMES),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_loop_scene_closes_after_one_lap() {
        let scene = build_scene(&SyntheticConfig::default());
        let last = scene.frames - 1;
        let end = scene.trajectory.pose(last as f64);
        let error = (end.to_homogeneous() - nalgebra::Matrix4::identity()).norm();
        assert!(error < 1e-9, "closure error {error}");
        assert!((225..=240).contains(&last), "{last} frames per lap");
    }

    #[test]
    fn every_camera_is_above_the_ground_with_a_wall_nearby() {
        for name in SceneName::ALL {
            let config = SyntheticConfig::for_scene(name);
            let scene = build_scene(&config);
            for i in (0..scene.frames).step_by(7) {
                let pose = scene.trajectory.pose(i as f64);
                let eye = Point3::from(pose.translation.vector);
                let down = scene.world.cast(&eye, &Vector3::y());
                assert!(
                    down.is_some_and(|h| (1.3..1.8).contains(&h.t)),
                    "{name} frame {i}: {down:?}"
                );
                let nearest_wall = (0..16)
                    .filter_map(|k| {
                        let a = k as f64 * std::f64::consts::TAU / 16.0;
                        scene.world.cast(&eye, &Vector3::new(a.cos(), 0.0, a.sin()))
                    })
                    .map(|h| h.t)
                    .fold(f64::INFINITY, f64::min);
                assert!(
                    (1.0..8.5).contains(&nearest_wall),
                    "{name} frame {i}: {nearest_wall}"
                );
            }
        }
    }
}
