//! The world: textured rectangles (one-sided), some with a stepped top edge
//! (a skyline of buildings of different heights), under a plain sky.

use nalgebra::{Point3, Vector3};

use super::rng::{hash_cell, unit_from_bits};
use super::texture::Texture;

/// A textured rectangle: the points `origin + u·u_axis + v·v_axis` with
/// `0 ≤ u ≤ u_length` and `0 ≤ v ≤ v_length` (or the skyline's height).
/// It is seen only from the side its normal `u_axis × v_axis` points to.
#[derive(Debug, Clone, PartialEq)]
pub struct Plane {
    /// The corner at `(u, v) = (0, 0)`.
    pub origin: Point3<f64>,
    /// Unit vector along `u`.
    pub u_axis: Vector3<f64>,
    /// Unit vector along `v`, orthogonal to `u_axis`.
    pub v_axis: Vector3<f64>,
    /// Extent along `u` (metres).
    pub u_length: f64,
    /// Extent along `v` (metres); with a skyline, the tallest possible height.
    pub v_length: f64,
    /// The surface's appearance in `(u, v)` metres.
    pub texture: Texture,
    /// A top edge that steps up and down along `u`, when set.
    pub skyline: Option<Skyline>,
}

/// Buildings of random heights side by side: along `u` the plane is cut
/// into segments, each with its own height (or none: a gap).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Skyline {
    /// Segment (building) width along `u` (metres).
    pub segment: f64,
    /// Lowest building height (metres).
    pub min_height: f64,
    /// Tallest building height (metres).
    pub max_height: f64,
    /// Probability that an odd-numbered segment is a gap (no building: a
    /// side street); even segments are always built, so gaps never merge.
    pub gap_probability: f64,
    /// Seed of the heights.
    pub seed: u64,
}

impl Skyline {
    /// The height of the building at `u` (0 in a gap).
    pub fn height_at(&self, u: f64) -> f64 {
        let index = super::noise::floor(u / self.segment) as i64;
        let h = hash_cell(self.seed, 2_000, index, 0);
        if index % 2 != 0 && unit_from_bits(h) < self.gap_probability {
            return 0.0;
        }
        let t = unit_from_bits(super::rng::mix64(h));
        self.min_height + t * (self.max_height - self.min_height)
    }
}

/// Where a ray meets a plane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Index of the plane in [`World::planes`].
    pub plane: usize,
    /// Ray parameter: the hit is `origin + t·direction`.
    pub t: f64,
    /// Surface coordinate `u` (metres).
    pub u: f64,
    /// Surface coordinate `v` (metres).
    pub v: f64,
}

impl Plane {
    /// A plane from its corner, two orthogonal directions (normalised here)
    /// and its extents.
    pub fn new(
        origin: Point3<f64>,
        u_axis: Vector3<f64>,
        v_axis: Vector3<f64>,
        u_length: f64,
        v_length: f64,
        texture: Texture,
    ) -> Self {
        Self {
            origin,
            u_axis: u_axis.normalize(),
            v_axis: v_axis.normalize(),
            u_length,
            v_length,
            texture,
            skyline: None,
        }
    }

    /// A vertical wall standing on the ground `y = ground_y` (y points
    /// down) from `(x, z) = from` to `to`, `height` metres tall, facing the
    /// right-hand side of the direction `from → to`. `u` runs along the
    /// ground from `from`, `v` upwards from the ground.
    pub fn wall(
        from: [f64; 2],
        to: [f64; 2],
        ground_y: f64,
        height: f64,
        texture: Texture,
    ) -> Self {
        let along = Vector3::new(to[0] - from[0], 0.0, to[1] - from[1]);
        Self::new(
            Point3::new(from[0], ground_y, from[1]),
            along,
            Vector3::new(0.0, -1.0, 0.0),
            along.norm(),
            height,
            texture,
        )
    }

    /// This plane with a skyline (its `v_length` becomes the tallest height).
    pub fn with_skyline(mut self, skyline: Skyline) -> Self {
        self.v_length = skyline.max_height;
        self.skyline = Some(skyline);
        self
    }

    /// The unit normal `u_axis × v_axis`: the side the plane is seen from.
    pub fn normal(&self) -> Vector3<f64> {
        self.u_axis.cross(&self.v_axis)
    }

    /// True when `(u, v)` lies on the plane's surface.
    pub fn contains(&self, u: f64, v: f64) -> bool {
        if !(0.0..=self.u_length).contains(&u) || !(0.0..=self.v_length).contains(&v) {
            return false;
        }
        self.skyline.is_none_or(|s| v <= s.height_at(u))
    }

    /// True when a camera at `eye` sees the plane's front side.
    pub fn faces(&self, eye: &Point3<f64>) -> bool {
        self.normal().dot(&(eye - self.origin)) > 0.0
    }

    /// The world point at surface coordinates `(u, v)`.
    pub fn point(&self, u: f64, v: f64) -> Point3<f64> {
        self.origin + self.u_axis * u + self.v_axis * v
    }
}

/// Planes under a sky whose gray level depends only on the direction.
#[derive(Debug, Clone, PartialEq)]
pub struct World {
    /// The surfaces.
    pub planes: Vec<Plane>,
    /// Sky gray level at the horizon.
    pub sky_horizon: f64,
    /// Sky gray level straight up.
    pub sky_zenith: f64,
}

impl World {
    /// A world of `planes` under a bright, featureless sky.
    pub fn new(planes: Vec<Plane>) -> Self {
        Self {
            planes,
            sky_horizon: 215.0,
            sky_zenith: 185.0,
        }
    }

    /// The sky's gray level seen along `direction` (y points down).
    pub fn sky(&self, direction: &Vector3<f64>) -> f64 {
        let elevation = (-direction.y / direction.norm()).clamp(0.0, 1.0);
        self.sky_horizon + (self.sky_zenith - self.sky_horizon) * elevation
    }

    /// The nearest front-side hit of the ray `origin + t·direction`, t > 0.
    pub fn cast(&self, origin: &Point3<f64>, direction: &Vector3<f64>) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        for (index, plane) in self.planes.iter().enumerate() {
            let n = plane.normal();
            let denom = n.dot(direction);
            if denom >= 0.0 {
                continue;
            }
            let t = n.dot(&(plane.origin - origin)) / denom;
            if t <= 0.0 || best.is_some_and(|b| t >= b.t) {
                continue;
            }
            let rel = origin + direction * t - plane.origin;
            let (u, v) = (rel.dot(&plane.u_axis), rel.dot(&plane.v_axis));
            if plane.contains(u, v) {
                best = Some(Hit {
                    plane: index,
                    t,
                    u,
                    v,
                });
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flat() -> Texture {
        Texture::Flat { gray: 100.0 }
    }

    #[test]
    fn a_wall_faces_the_right_of_its_direction() {
        // Along +z, the right-hand side is +x (x right, y down, z forward).
        let wall = Plane::wall([3.0, 0.0], [3.0, 10.0], 1.5, 5.0, flat());
        assert!((wall.normal() - Vector3::new(1.0, 0.0, 0.0)).norm() < 1e-12);
        assert!(wall.faces(&Point3::new(5.0, 0.0, 0.0)));
        assert!(!wall.faces(&Point3::origin()));
        assert_eq!(wall.point(0.0, 1.5), Point3::new(3.0, 0.0, 0.0));
    }

    #[test]
    fn the_nearest_front_face_is_hit() {
        let near = Plane::new(
            Point3::new(-5.0, 5.0, 4.0),
            Vector3::x(),
            -Vector3::y(),
            10.0,
            10.0,
            flat(),
        );
        let mut far = near.clone();
        far.origin.z = 9.0;
        let world = World::new(vec![far, near]);
        let hit = world.cast(&Point3::origin(), &Vector3::z()).unwrap();
        assert_eq!(hit.plane, 1);
        assert!((hit.t - 4.0).abs() < 1e-12);
        // Seen from behind, neither plane exists.
        assert!(world
            .cast(&Point3::new(0.0, 0.0, 20.0), &Vector3::z())
            .is_none());
    }

    #[test]
    fn skyline_heights_stay_in_range_with_some_gaps() {
        let s = Skyline {
            segment: 10.0,
            min_height: 8.0,
            max_height: 20.0,
            gap_probability: 0.2,
            seed: 3,
        };
        let heights: Vec<f64> = (0..200)
            .map(|i| s.height_at(i as f64 * 10.0 + 5.0))
            .collect();
        assert!(heights
            .iter()
            .all(|&h| h == 0.0 || (8.0..=20.0).contains(&h)));
        let gaps = heights.iter().filter(|&&h| h == 0.0).count();
        assert!((10..=30).contains(&gaps), "{gaps} gaps of 200");
        assert_eq!(s.height_at(12.0), s.height_at(19.0));
    }
}
