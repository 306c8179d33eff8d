//! The built-in scenes: a city block (driven around), a straight street,
//! a ring corridor (walked with a hand-held camera), an open highway
//! (most of the texture far from the road) and a straight street with two
//! look-alike places (perceptual aliasing).

use nalgebra::{Point3, Vector3};

use super::config::{SceneName, SyntheticConfig};
use super::rng::{mix64, SplitMix64};
use super::styles::{self, Facades};
use super::trajectory::{PathShape, Trajectory, Wobble};
use super::world::{Plane, Skyline, World};

/// Camera height above the road (KITTI's, metres).
const CAR_CAMERA_HEIGHT: f64 = 1.65;
/// Camera height above the floor for the walker (metres).
const WALKER_CAMERA_HEIGHT: f64 = 1.5;
/// Frames of the open-path scenes when the config does not say.
const DEFAULT_OPEN_FRAMES: usize = 200;
/// Frames of the `highway` scene when the config does not say; its world
/// is never shorter than this many frames of driving.
const DEFAULT_HIGHWAY_FRAMES: usize = 300;

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
///
/// A condition's manoeuvre (a turn in place, a jump back) is placed in the
/// middle of the frames the scene has without it, and adds its frames, so
/// the path still ends where it would.
pub fn build_scene(config: &SyntheticConfig) -> Scene {
    let nominal_step = config.speed / config.fps;
    let mut scene = match config.scene {
        SceneName::Loop => block_ring(config, nominal_step),
        SceneName::Straight => straight_street(config, nominal_step),
        SceneName::Wobbly => ring_corridor(config, nominal_step),
        SceneName::Highway => highway(config, nominal_step),
        SceneName::Aliasing => aliasing_street(config, nominal_step),
    };
    if let Some(manoeuvre) = config.condition.manoeuvre(scene.frames) {
        scene.trajectory.manoeuvre = Some(manoeuvre);
        scene.frames += manoeuvre.extra_frames();
    }
    scene
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
    let facades = config.condition.facades();
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
        building_row(a, b, ground, (mix64(seed ^ (10 + i)), facades), 0.0)
    });
    planes.extend(rectangle_walls(outer_x, outer_z, false, |a, b, i| {
        building_row(a, b, ground, (mix64(seed ^ (20 + i)), facades), 0.25)
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
            manoeuvre: None,
        },
        frames: config.frames.unwrap_or(frames_per_lap + 1),
    }
}

/// A row of façades of different heights from `from` to `to`.
fn building_row(
    from: [f64; 2],
    to: [f64; 2],
    ground: f64,
    (seed, facades): (u64, Facades),
    gaps: f64,
) -> Plane {
    Plane::wall(from, to, ground, 0.0, facades.texture(seed)).with_skyline(Skyline {
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
    let facades = config.condition.facades();
    let seed = config.seed;
    let frames = config.frames.unwrap_or(DEFAULT_OPEN_FRAMES);
    let far = frames as f64 * step + 80.0;
    let ground = CAR_CAMERA_HEIGHT;
    let (left_x, right_x, back) = (-8.0, 6.0, -30.0);
    let planes = vec![
        building_row(
            [left_x, back],
            [left_x, far],
            ground,
            (mix64(seed ^ 40), facades),
            0.3,
        ),
        building_row(
            [right_x, far],
            [right_x, back],
            ground,
            (mix64(seed ^ 41), facades),
            0.3,
        ),
        Plane::wall(
            [-60.0, far],
            [60.0, far],
            ground,
            30.0,
            facades.texture(mix64(seed ^ 42)),
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
            manoeuvre: None,
        },
        frames,
    }
}

/// Where the `aliasing` scene's two look-alike places stand along its
/// straight street (the camera's path is the line x = 0, y = 0; frame `i`
/// is at z = `i·step`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AliasingLayout {
    /// Start and end (z, metres) of place A.
    pub place_a: [f64; 2],
    /// Start and end (z, metres) of place B: as long as place A.
    pub place_b: [f64; 2],
    /// Distances (metres) of place A's left and right walls from the path.
    pub walls_a: [f64; 2],
    /// Distances (metres) of place B's left and right walls from the path.
    pub walls_b: [f64; 2],
    /// Distances (metres) of the ordinary street's left and right walls.
    pub street_walls: [f64; 2],
    /// Ordinary street driven past place B by the default frame count (metres).
    pub street_after: f64,
}

/// The `aliasing` scene's layout (see [`AliasingLayout`]): place A over
/// z ∈ [70, 100) m, 70 m of ordinary street, place B over z ∈ [170, 200) m;
/// A's walls 4.5 m (left) and 6 m (right) from the path, B's 6.5 m and
/// 8 m; the ordinary street's 7 m and 6 m.
pub const ALIASING_LAYOUT: AliasingLayout = AliasingLayout {
    place_a: [70.0, 100.0],
    place_b: [170.0, 200.0],
    walls_a: [4.5, 6.0],
    walls_b: [6.5, 8.0],
    street_walls: [7.0, 6.0],
    street_after: 100.0,
};

impl AliasingLayout {
    /// The frames whose camera stands inside `place` (`[start, end]`
    /// metres) at `step` metres per frame: the first and the last index.
    pub fn frames_in(place: [f64; 2], step: f64) -> [usize; 2] {
        [
            (place[0] / step).ceil().max(0.0) as usize,
            (place[1] / step).floor().max(0.0) as usize,
        ]
    }

    /// The default number of frames at `step` metres per frame: from the
    /// start to `street_after` metres past place B.
    pub fn default_frames(&self, step: f64) -> usize {
        (((self.place_b[1] + self.street_after) / step).round() as usize).max(1)
    }
}

/// One façade stretch on one side of a straight street along +z.
struct Stretch {
    /// Start and end (z, metres).
    z: [f64; 2],
    /// Distance from the path (metres).
    distance: f64,
    /// Seed of the texture and the skyline.
    seed: u64,
    /// Probability of a side-street gap (see [`Skyline`]).
    gaps: f64,
}

/// The façades of one side of a straight street (`left`: x < 0) made of
/// `stretches` in order along +z, each a [`building_row`] whose `u` starts
/// at its own beginning (left) or end (right), so that two stretches with
/// the same seed and length look exactly alike. Where the distance
/// changes, the side face of the building that stands out closes the gap.
fn street_side(stretches: &[Stretch], left: bool, ground: f64, facades: Facades) -> Vec<Plane> {
    let sign = if left { -1.0 } else { 1.0 };
    let row = |s: &Stretch| {
        let (x, [z0, z1]) = (sign * s.distance, s.z);
        // A wall faces the right of its direction: +x on the left side.
        let (from, to) = if left {
            ([x, z0], [x, z1])
        } else {
            ([x, z1], [x, z0])
        };
        building_row(from, to, ground, (s.seed, facades), s.gaps)
    };
    // The skyline height of `s`'s row at z (just inside its ends).
    let height_at = |s: &Stretch, plane: &Plane, z: f64| {
        let eps = 1e-6;
        let u = if left { z - s.z[0] } else { s.z[1] - z };
        let u = u.clamp(eps, plane.u_length - eps);
        plane.skyline.map_or(plane.v_length, |k| k.height_at(u))
    };
    let rows: Vec<Plane> = stretches.iter().map(row).collect();
    let mut planes = rows.clone();
    for (i, pair) in stretches.windows(2).enumerate() {
        let (before, after) = (&pair[0], &pair[1]);
        let z = after.z[0];
        if (before.distance - after.distance).abs() < 1e-9 {
            continue;
        }
        // The side face belongs to the building nearer the road.
        let (owner, plane) = if after.distance < before.distance {
            (after, &rows[i + 1])
        } else {
            (before, &rows[i])
        };
        let height = height_at(owner, plane, z);
        if height <= 0.0 {
            continue;
        }
        // Facing −z where the street narrows, +z where it widens.
        let (x_before, x_after) = (sign * before.distance, sign * after.distance);
        let (from, to) = if left {
            ([x_before, z], [x_after, z])
        } else {
            ([x_after, z], [x_before, z])
        };
        planes.push(Plane::wall(
            from,
            to,
            ground,
            height,
            facades.texture(mix64(owner.seed ^ 1)),
        ));
    }
    planes
}

/// The `aliasing` scene: a straight street driven at 10 m/s (1 m per
/// frame) that passes two look-alike places, A and B, for perceptual-
/// aliasing tests of loop detection (see [`ALIASING_LAYOUT`]).
///
/// * Places A (z ∈ [70, 100) m) and B (z ∈ [170, 200) m) are 30 m of
///   façades on both sides whose textures and skylines are exactly the
///   same: the same seeds and styles, and the same texture coordinates
///   relative to the start of the place. Appearance retrieval (bag of
///   words, VLAD) finds B similar to A.
/// * But the walls stand at different distances from the path: 4.5 m
///   (left) and 6 m (right) at A, a 10.5-m street; 6.5 m and 8 m at B, a
///   14.5-m street. No single rigid transform maps A's 3-D points onto
///   B's (it would have to move the left wall 2 m left and the right wall
///   2 m right), so a metric check of A ↔ B (stereo points, PnP or a
///   rigid fit) must fail. Two limits: each wall on its own is a rigid
///   copy (its points are shifted 2 m sideways and 100 m along the
///   street), so a check that accepts the inliers of one wall alone is
///   fooled; and since the walls only move sideways, every A ↔ B
///   correspondence stays on its image row, which one epipolar geometry
///   (a sideways translation's) explains for both walls: a
///   fundamental-matrix check alone cannot reject the pair.
/// * Everywhere else the street is ordinary: façades 7 m (left) and 6 m
///   (right) from the path with side-street gaps, a new texture seed for
///   each stretch (before A, the 70 m between A and B, after B), one
///   asphalt road and a wall far ahead. Where the wall distance changes,
///   the side face of the nearer building closes the gap.
///
/// At the default 1 m per frame the camera stands in place A in frames
/// 70–100 and in place B in frames 170–200; the default 300 frames end
/// 100 m past B. The places do not move with the speed or the frame count.
fn aliasing_street(config: &SyntheticConfig, step: f64) -> Scene {
    let facades = config.condition.facades();
    let seed = config.seed;
    let layout = ALIASING_LAYOUT;
    let frames = config.frames.unwrap_or_else(|| layout.default_frames(step));
    let ground = CAR_CAMERA_HEIGHT;
    let back = -30.0;
    let far = (frames as f64 * step).max(layout.place_b[1]) + 80.0;
    let mut planes = Vec::new();
    for (side, left) in [(0usize, true), (1, false)] {
        let street = |k: u64, z: [f64; 2]| Stretch {
            z,
            distance: layout.street_walls[side],
            seed: mix64(seed ^ (110 + 2 * k + side as u64)),
            gaps: 0.3,
        };
        // The same seed at both places: the look-alike façades.
        let place = |z: [f64; 2], walls: [f64; 2]| Stretch {
            z,
            distance: walls[side],
            seed: mix64(seed ^ (120 + side as u64)),
            gaps: 0.0,
        };
        let stretches = [
            street(0, [back, layout.place_a[0]]),
            place(layout.place_a, layout.walls_a),
            street(1, [layout.place_a[1], layout.place_b[0]]),
            place(layout.place_b, layout.walls_b),
            street(2, [layout.place_b[1], far]),
        ];
        planes.extend(street_side(&stretches, left, ground, facades));
    }
    planes.push(Plane::wall(
        [-60.0, far],
        [60.0, far],
        ground,
        30.0,
        facades.texture(mix64(seed ^ 130)),
    ));
    planes.push(horizontal(
        ground,
        [-60.0, 60.0],
        [back, far],
        true,
        styles::asphalt(mix64(seed ^ 131)),
    ));
    Scene {
        world: World::new(planes),
        trajectory: Trajectory {
            shape: PathShape::Straight,
            step,
            fps: config.fps,
            wobble: None,
            manoeuvre: None,
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
            manoeuvre: None,
        },
        frames: config.frames.unwrap_or(DEFAULT_OPEN_FRAMES),
    }
}

/// The `highway` scene: a straight open road, driven in its right lane
/// at 25 m/s (2.5 m per frame), for 300 frames by default.
///
/// * Ground: a 12-m carriageway (x ∈ [−8, 4]) of asphalt between grass
///   verges reaching 160 m to each side.
/// * Far (most of the image above the horizon): on each side two rows of
///   skylines facing the road, 10–40-m buildings with gaps at 45 m (left)
///   and 60 m (right), 60–150-m hillsides behind them at 110 m and 140 m;
///   25–70-m ridges facing the car every ~110 m between the rows (48–135 m
///   from the road, so that some far texture is ahead, not only beside);
///   and a 100–200-m hill across the road 150 m past the last frame.
/// * Near, sparse: every 45–75 m a road sign, a barrier panel or a
///   roadside cabinet, 5.5–14 m from the car's path, so a handful are in
///   view at once.
///
/// About 45 planes for the default 300 frames; the world grows with
/// `frames × step` (at least 300 frames' worth).
fn highway(config: &SyntheticConfig, step: f64) -> Scene {
    let facades = config.condition.facades();
    let seed = config.seed;
    let frames = config.frames.unwrap_or(DEFAULT_HIGHWAY_FRAMES);
    let ground = CAR_CAMERA_HEIGHT;
    // Where the road ends: the far hill, 150 m past the last frame.
    let end = frames.max(DEFAULT_HIGHWAY_FRAMES) as f64 * step + 150.0;
    let back = -60.0;
    let (road_left, road_right, verge) = (-8.0, 4.0, 160.0);
    let mut planes = vec![
        horizontal(
            ground,
            [road_left, road_right],
            [back, end],
            true,
            styles::asphalt(mix64(seed ^ 80)),
        ),
        horizontal(
            ground,
            [-verge, road_left],
            [back, end],
            true,
            styles::verge(mix64(seed ^ 81)),
        ),
        horizontal(
            ground,
            [road_right, verge],
            [back, end],
            true,
            styles::verge(mix64(seed ^ 82)),
        ),
    ];
    // Rows along the road, facing it: (x, segment, heights, gaps, hills?).
    let rows = [
        (-45.0, 24.0, [10.0, 35.0], 0.6, false),
        (-110.0, 45.0, [60.0, 130.0], 0.0, true),
        (60.0, 30.0, [12.0, 40.0], 0.6, false),
        (140.0, 55.0, [70.0, 150.0], 0.0, true),
    ];
    for (i, (x, segment, [low, high], gaps, hills)) in rows.into_iter().enumerate() {
        let row_seed = mix64(seed ^ (83 + i as u64));
        // A wall faces the right of its direction: +z on the left, −z on the right.
        let (from, to) = if x < 0.0 {
            ([x, back], [x, end])
        } else {
            ([x, end], [x, back])
        };
        planes.push(far_skyline(
            from,
            to,
            ground,
            row_seed,
            segment,
            [low, high],
            gaps,
            hills,
        ));
    }
    // Ridges facing the car between the rows, alternately left and right.
    let mut rng = SplitMix64::new(mix64(seed ^ 90));
    let mut z = 60.0 + rng.uniform(0.0, 40.0);
    let mut k = 0u64;
    while z < end - 60.0 {
        let span = if k.is_multiple_of(2) {
            [-105.0, -48.0]
        } else {
            [63.0, 135.0]
        };
        let ridge_seed = mix64(seed ^ (100 + k));
        planes.push(far_skyline(
            [span[0], z],
            [span[1], z],
            ground,
            ridge_seed,
            15.0,
            [25.0, 70.0],
            0.3,
            k % 4 >= 2,
        ));
        z += rng.uniform(90.0, 130.0);
        k += 1;
    }
    planes.push(far_skyline(
        [-300.0, end],
        [300.0, end],
        ground,
        mix64(seed ^ 91),
        60.0,
        [100.0, 200.0],
        0.0,
        true,
    ));
    planes.extend(roadside_objects(seed, ground, end - 60.0, facades));
    Scene {
        world: World::new(planes),
        trajectory: Trajectory {
            shape: PathShape::Straight,
            step,
            fps: config.fps,
            wobble: None,
            manoeuvre: None,
        },
        frames,
    }
}

/// A far skyline from `from` to `to` (facing the right of that direction):
/// buildings (`hills` false) or a hillside, `segment` metres wide pieces of
/// heights in `heights`, odd pieces missing with probability `gaps`.
#[allow(clippy::too_many_arguments)]
fn far_skyline(
    from: [f64; 2],
    to: [f64; 2],
    ground: f64,
    seed: u64,
    segment: f64,
    [min_height, max_height]: [f64; 2],
    gaps: f64,
    hills: bool,
) -> Plane {
    let texture = if hills {
        styles::hillside(seed)
    } else {
        styles::distant_buildings(seed)
    };
    Plane::wall(from, to, ground, 0.0, texture).with_skyline(Skyline {
        segment,
        min_height,
        max_height,
        gap_probability: gaps,
        seed,
    })
}

/// Sparse roadside objects along `z` ∈ [25 m, `until`]: every 45–75 m, on
/// a random side, a sign board turned 20° towards the road (6–12 m right
/// or 10–14 m left of the path, 1.5–2.5 m above the ground), a barrier
/// panel along the road (5.5–7 m right or 9.5–11 m left) or a cabinet
/// (its front and its road-side face, 7–14 m away).
fn roadside_objects(seed: u64, ground: f64, until: f64, facades: Facades) -> Vec<Plane> {
    let mut rng = SplitMix64::new(mix64(seed ^ 95));
    let mut planes = Vec::new();
    let mut z = 25.0 + rng.uniform(0.0, 20.0);
    let mut k = 0u64;
    while z < until {
        let texture_seed = mix64(seed ^ (200 + k));
        // +1: right of the road, −1: left.
        let side = if rng.next_unit() < 0.5 { 1.0 } else { -1.0 };
        let kind = rng.next_unit();
        if kind < 0.4 {
            let lateral = if side > 0.0 {
                rng.uniform(6.0, 12.0)
            } else {
                rng.uniform(10.0, 14.0)
            };
            let (width, height) = (rng.uniform(3.0, 4.5), rng.uniform(2.0, 3.0));
            let bottom = rng.uniform(1.5, 2.5);
            let angle = 20f64.to_radians();
            // Normal (−side·sin a, 0, −cos a): facing the car and the road.
            let u_axis = Vector3::new(angle.cos(), 0.0, -side * angle.sin());
            let centre = Point3::new(side * lateral, ground - bottom, z);
            planes.push(Plane::new(
                centre - u_axis * (0.5 * width),
                u_axis,
                -Vector3::y(),
                width,
                height,
                styles::indoor_wall(texture_seed),
            ));
        } else if kind < 0.7 {
            let lateral = if side > 0.0 {
                rng.uniform(5.5, 7.0)
            } else {
                rng.uniform(9.5, 11.0)
            };
            let (length, height) = (rng.uniform(10.0, 18.0), rng.uniform(1.2, 2.5));
            let x = side * lateral;
            let (from, to) = if side > 0.0 {
                ([x, z + length], [x, z])
            } else {
                ([x, z], [x, z + length])
            };
            planes.push(Plane::wall(
                from,
                to,
                ground,
                height,
                facades.texture(texture_seed),
            ));
        } else {
            let near = rng.uniform(7.0, 14.0);
            let (width, depth) = (rng.uniform(2.0, 3.0), rng.uniform(3.0, 6.0));
            let height = rng.uniform(2.2, 3.5);
            let (x_near, x_far) = (side * near, side * (near + width));
            let texture = facades.texture(texture_seed);
            let (front_from, front_to) = if side > 0.0 {
                ([x_near, z], [x_far, z])
            } else {
                ([x_far, z], [x_near, z])
            };
            planes.push(Plane::wall(
                front_from,
                front_to,
                ground,
                height,
                texture.clone(),
            ));
            let (side_from, side_to) = if side > 0.0 {
                ([x_near, z + depth], [x_near, z])
            } else {
                ([x_near, z], [x_near, z + depth])
            };
            planes.push(Plane::wall(side_from, side_to, ground, height, texture));
        }
        z += rng.uniform(45.0, 75.0);
        k += 1;
    }
    planes
}

#[cfg(test)]
mod tests {
    use super::super::world::Hit;
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
                // An open road for the highway, a street or corridor otherwise.
                let range = if name == SceneName::Highway {
                    5.0..200.0
                } else {
                    1.0..8.5
                };
                assert!(
                    range.contains(&nearest_wall),
                    "{name} frame {i}: {nearest_wall}"
                );
            }
        }
    }

    #[test]
    fn the_highway_is_clear_and_long_enough() {
        let config = SyntheticConfig::for_scene(SceneName::Highway);
        let scene = build_scene(&config);
        assert_eq!(scene.frames, 300);
        assert!((scene.trajectory.step - 2.5).abs() < 1e-12);
        assert!(
            scene.world.planes.len() < 60,
            "{} planes",
            scene.world.planes.len()
        );
        for i in 0..scene.frames {
            let eye = Point3::from(scene.trajectory.pose(i as f64).translation.vector);
            // Nothing on the road between this frame and the next.
            let ahead = scene.world.cast(&eye, &Vector3::z()).expect("a hill ahead");
            assert!(ahead.t > 100.0, "frame {i}: {ahead:?}");
            // The car's roof (1.65 m up) and its sides stay clear too.
            for offset in [Vector3::new(-1.0, 0.0, 0.0), Vector3::new(1.0, 0.0, 0.0)] {
                let hit = scene.world.cast(&(eye + offset), &Vector3::z());
                assert!(hit.is_some_and(|h| h.t > 100.0), "frame {i}: {hit:?}");
            }
        }
        // Longer sequences get a longer world.
        let mut long = config.clone();
        long.frames = Some(600);
        let scene = build_scene(&long);
        let eye = Point3::from(scene.trajectory.pose(599.0).translation.vector);
        let ahead = scene.world.cast(&eye, &Vector3::z()).unwrap();
        assert!((100.0..=160.0).contains(&ahead.t), "{ahead:?}");
    }

    #[test]
    fn the_aliasing_street_is_straight_and_forward() {
        let config = SyntheticConfig::for_scene(SceneName::Aliasing);
        let scene = build_scene(&config);
        let layout = ALIASING_LAYOUT;
        assert!((scene.trajectory.step - 1.0).abs() < 1e-12);
        assert_eq!(scene.frames, 300);
        assert_eq!(scene.trajectory.shape, PathShape::Straight);
        assert!(scene.trajectory.wobble.is_none());
        for i in 0..scene.frames {
            let pose = scene.trajectory.pose(i as f64);
            let t = pose.translation.vector;
            assert!(
                t.x.abs() < 1e-12 && t.y.abs() < 1e-12 && (t.z - i as f64).abs() < 1e-9,
                "frame {i}: {t}"
            );
            assert!(pose.rotation.angle() < 1e-12, "frame {i}");
        }
        // A, at least 40 m of street, B, and street after B.
        let last_z = (scene.frames - 1) as f64 * scene.trajectory.step;
        assert!(layout.place_b[0] - layout.place_a[1] >= 40.0);
        assert!((25.0..=30.0).contains(&(layout.place_a[1] - layout.place_a[0])));
        assert_eq!(
            layout.place_a[1] - layout.place_a[0],
            layout.place_b[1] - layout.place_b[0]
        );
        assert!(last_z > layout.place_b[1] + 50.0, "{last_z}");
        assert_eq!(AliasingLayout::frames_in(layout.place_a, 1.0), [70, 100]);
        assert_eq!(AliasingLayout::frames_in(layout.place_b, 1.0), [170, 200]);
        // The places stay put at other speeds; the frame count follows.
        let mut fast = config.clone();
        fast.speed = 20.0;
        assert_eq!(build_scene(&fast).frames, 150);
    }

    /// Where a ray from a camera 5 m before `z` towards the point
    /// `(x, −height, z)` (height above the road) hits the aliasing street.
    fn aliasing_hit(scene: &Scene, x: f64, height: f64, z: f64) -> Option<(Hit, Plane)> {
        let eye = Point3::new(0.0, 0.0, z - 5.0);
        let target = Point3::new(x, CAR_CAMERA_HEIGHT - height, z);
        let hit = scene.world.cast(&eye, &(target - eye))?;
        Some((hit, scene.world.planes[hit.plane].clone()))
    }

    #[test]
    fn the_two_places_look_alike_at_different_distances() {
        let scene = build_scene(&SyntheticConfig::for_scene(SceneName::Aliasing));
        let layout = ALIASING_LAYOUT;
        let shift = layout.place_b[0] - layout.place_a[0];
        let (mut compared, mut different) = (0, 0);
        for side in [0usize, 1] {
            let sign = if side == 0 { -1.0 } else { 1.0 };
            for k in 0..13 {
                let along = 3.0 + 2.0 * k as f64;
                for height in [2.0, 4.5] {
                    let z = layout.place_a[0] + along;
                    let (a, plane_a) =
                        aliasing_hit(&scene, sign * layout.walls_a[side], height, z).unwrap();
                    let (b, plane_b) =
                        aliasing_hit(&scene, sign * layout.walls_b[side], height, z + shift)
                            .unwrap();
                    // The same texture at the same surface coordinates…
                    assert_eq!(plane_a.texture, plane_b.texture, "side {side} at {along} m");
                    assert_eq!(plane_a.skyline, plane_b.skyline);
                    assert!(
                        (a.u - b.u).abs() < 1e-6 && (a.v - b.v).abs() < 1e-6,
                        "side {side} at {along} m: {a:?} {b:?}"
                    );
                    // …but on a wall at another distance from the path.
                    let gap = (plane_a.origin.x - plane_b.origin.x).abs();
                    assert!((gap - 2.0).abs() < 1e-9, "side {side}: {gap}");
                    // The ordinary street between them looks different
                    // (or shows a side-street gap).
                    let between = layout.place_a[1] + 20.0 + along;
                    let c = aliasing_hit(&scene, sign * layout.street_walls[side], height, between);
                    if let Some((_, plane_c)) = c {
                        assert_ne!(plane_a.texture, plane_c.texture);
                        different += 1;
                    }
                    compared += 1;
                }
            }
        }
        assert_eq!(compared, 52);
        assert!(different > 26, "{different}");
        // Both sides widen at B: no single translation maps A onto B.
        let left_shift = layout.walls_a[0] - layout.walls_b[0];
        let right_shift = layout.walls_b[1] - layout.walls_a[1];
        assert!((right_shift - left_shift).abs() >= 3.0);
    }
}
