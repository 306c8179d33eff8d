//! Ray casting: for each pixel centre, the nearest plane hit gives the gray
//! level (box-filtered over the pixel's footprint on the surface, from ray
//! differentials) and the depth Z in the camera frame.
//!
//! The image is cut into 16×16-pixel tiles, and a tile's rays are tested
//! only against the planes that reach its viewing cone (the others cannot
//! be hit, so the result is the same as testing every plane): a world of
//! many small or distant planes costs little more than a few large ones.

use nalgebra::{Isometry3, Point3, Vector3};

use super::camera::StereoCamera;
use super::texture::Footprint;
use super::world::{Plane, World};

/// A noiseless rendering of one camera.
#[derive(Debug, Clone, PartialEq)]
pub struct View {
    /// Image width (pixels).
    pub width: usize,
    /// Image height (pixels).
    pub height: usize,
    /// Gray levels, row-major, not clamped.
    pub gray: Vec<f32>,
    /// Depth Z in the camera frame (metres), row-major; 0 where the sky is
    /// seen. Empty when depth was not asked for.
    pub depth: Vec<f32>,
}

/// Side (pixels) of the square tiles whose rays share a list of planes.
const TILE: usize = 16;
/// How far (pixels) a tile's cone reaches past its pixel centres: half a
/// pixel for the pixel corners and sub-samples, one more for rounding.
const TILE_MARGIN: f64 = 1.5;

/// A plane with the per-view quantities of the intersection precomputed.
struct Visible<'a> {
    plane: &'a Plane,
    normal: Vector3<f64>,
    /// `normal · (origin − eye)`: negative for a plane seen from the front.
    offset: f64,
    /// `eye − origin`.
    eye_from_origin: Vector3<f64>,
    /// The rectangle's four corners relative to the eye, in the camera
    /// frame (a skyline only cuts the rectangle down).
    corners: [Vector3<f64>; 4],
}

impl Visible<'_> {
    /// False when no ray `(X, Y, 1)` (camera frame) with `X ∈ [x0, x1]`,
    /// `Y ∈ [y0, y1]` can meet the plane: all four corners (hence the whole
    /// convex rectangle) lie outside one side of that cone.
    fn reaches(&self, [x0, x1]: [f64; 2], [y0, y1]: [f64; 2]) -> bool {
        let outside = |side: fn(&Vector3<f64>, f64) -> f64, bound: f64| {
            self.corners.iter().all(|q| side(q, bound) < 0.0)
        };
        !(outside(|q, x0| q.x - x0 * q.z, x0)
            || outside(|q, x1| x1 * q.z - q.x, x1)
            || outside(|q, y0| q.y - y0 * q.z, y0)
            || outside(|q, y1| y1 * q.z - q.y, y1))
    }
}

/// Per-view constants shared by every row.
struct ViewSetup<'a> {
    world: &'a World,
    visible: Vec<Visible<'a>>,
    /// Ray of the pixel (0, 0) in the camera frame (z = 1).
    corner_ray_camera: Vector3<f64>,
    /// Change of the camera-frame ray per pixel along x and y.
    inverse_focal: [f64; 2],
    /// Ray of the pixel (0, 0) in the world frame (camera z = 1).
    corner_ray: Vector3<f64>,
    /// Change of the ray per pixel along x and y.
    step_x: Vector3<f64>,
    step_y: Vector3<f64>,
    width: usize,
    height: usize,
}

/// The visible planes each tile of a band of tile rows can see, in the
/// order of [`ViewSetup::visible`].
struct TilePlanes {
    first_tile_row: usize,
    columns: usize,
    /// `ends[k]`: where tile `k`'s list ends in `planes` (row-major tiles).
    ends: Vec<usize>,
    planes: Vec<u32>,
}

impl TilePlanes {
    /// The planes the rays of pixel `(x, y)` (±`TILE_MARGIN`) may hit.
    fn at(&self, x: usize, y: usize) -> &[u32] {
        let k = (y / TILE - self.first_tile_row) * self.columns + x / TILE;
        let start = if k == 0 { 0 } else { self.ends[k - 1] };
        &self.planes[start..self.ends[k]]
    }
}

/// The number of threads `threads` asks for (0: every core).
pub fn thread_count(threads: usize) -> usize {
    if threads > 0 {
        threads
    } else {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    }
}

/// Renders the world seen by a camera at `pose_wc` (T_wc), with the depth
/// map when `with_depth`, splitting rows over `threads` threads (0: all cores).
pub fn render_view(
    world: &World,
    camera: &StereoCamera,
    pose_wc: &Isometry3<f64>,
    with_depth: bool,
    threads: usize,
) -> View {
    let (width, height) = (camera.width, camera.height);
    let setup = ViewSetup::new(world, camera, pose_wc);
    let mut gray = vec![0f32; width * height];
    let mut depth = if with_depth {
        vec![0f32; width * height]
    } else {
        Vec::new()
    };
    let threads = thread_count(threads).clamp(1, height);
    let rows_per_chunk = height.div_ceil(threads);
    let chunk = rows_per_chunk * width;
    std::thread::scope(|scope| {
        let mut depth_chunks = depth.chunks_mut(chunk.max(1));
        for (index, gray_chunk) in gray.chunks_mut(chunk).enumerate() {
            let depth_chunk = depth_chunks.next();
            let setup = &setup;
            scope.spawn(move || setup.render_rows(index * rows_per_chunk, gray_chunk, depth_chunk));
        }
    });
    View {
        width,
        height,
        gray,
        depth,
    }
}

/// The nearest plane along a ray: index into the visible planes, ray
/// parameter, surface coordinates and `normal · ray`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct RayHit {
    visible: usize,
    t: f64,
    u: f64,
    v: f64,
    denom: f64,
}

/// Marks the sky in the corner-id grid.
const SKY: u32 = u32::MAX;
/// Sub-pixel offsets of the 4×4 samples taken on silhouette pixels.
const SUBSAMPLES: [f64; 4] = [-0.375, -0.125, 0.125, 0.375];

impl<'a> ViewSetup<'a> {
    /// The planes `world` shows a camera at `pose_wc` (T_wc), and the rays.
    fn new(world: &'a World, camera: &StereoCamera, pose_wc: &Isometry3<f64>) -> Self {
        let eye = Point3::from(pose_wc.translation.vector);
        let rotation = pose_wc.rotation.to_rotation_matrix();
        let to_camera = rotation.transpose();
        let visible = world
            .planes
            .iter()
            .filter(|p| p.faces(&eye))
            .map(|plane| {
                let normal = plane.normal();
                let corner = |u: f64, v: f64| to_camera * (plane.point(u, v) - eye);
                Visible {
                    plane,
                    normal,
                    offset: normal.dot(&(plane.origin - eye)),
                    eye_from_origin: eye - plane.origin,
                    corners: [
                        corner(0.0, 0.0),
                        corner(plane.u_length, 0.0),
                        corner(0.0, plane.v_length),
                        corner(plane.u_length, plane.v_length),
                    ],
                }
            })
            .collect();
        Self {
            world,
            visible,
            corner_ray_camera: camera.ray(0.0, 0.0),
            inverse_focal: [1.0 / camera.fx, 1.0 / camera.fy],
            corner_ray: rotation * camera.ray(0.0, 0.0),
            step_x: rotation * Vector3::new(1.0 / camera.fx, 0.0, 0.0),
            step_y: rotation * Vector3::new(0.0, 1.0 / camera.fy, 0.0),
            width: camera.width,
            height: camera.height,
        }
    }

    /// Renders the rows starting at `first_row` into the given slices.
    ///
    /// A pixel is shaded at its centre, box-filtered over its footprint on
    /// the surface. Where a silhouette crosses it (its four corners and its
    /// centre do not all see the same plane) it is the mean of 4×4 samples,
    /// so plane edges are antialiased too. Depth is always the centre's.
    fn render_rows(&self, first_row: usize, gray: &mut [f32], mut depth: Option<&mut [f32]>) {
        let width = self.width;
        let rows = gray.len() / width;
        // The corner ids reach one row into the next chunk.
        let last_row = (first_row + rows).min(self.height - 1);
        let tiles = self.tile_planes(first_row / TILE..last_row / TILE + 1);
        let corners = self.corner_ids(first_row, rows, &tiles);
        for (row_offset, gray_row) in gray.chunks_mut(width).enumerate() {
            let row = first_row + row_offset;
            let y = row as f64;
            for (x, pixel) in gray_row.iter_mut().enumerate() {
                let ray = self.ray(x as f64, y);
                let top = &corners[row_offset * (width + 1) + x..][..2];
                let bottom = &corners[(row_offset + 1) * (width + 1) + x..][..2];
                let id = top[0];
                let uniform = top[1] == id && bottom[0] == id && bottom[1] == id;
                // Planes are far wider than a pixel: when the four corners
                // see one plane, so does the centre (checked, not assumed).
                let centre = if !uniform {
                    None
                } else if id == SKY {
                    Some(None)
                } else {
                    self.intersect_plane(id as usize, &ray).map(Some)
                };
                let (value, hit) = match centre {
                    Some(hit) => (self.shade(&ray, hit.as_ref(), 1.0), hit),
                    None => {
                        let planes = tiles.at(x, row);
                        (
                            self.supersample(x as f64, y, planes),
                            self.intersect(&ray, planes),
                        )
                    }
                };
                *pixel = value as f32;
                if let Some(depth) = depth.as_deref_mut() {
                    depth[row_offset * width + x] = hit.map_or(0.0, |h| h.t) as f32;
                }
            }
        }
    }

    /// The world ray (camera z = 1) through image point `(x, y)`.
    fn ray(&self, x: f64, y: f64) -> Vector3<f64> {
        self.corner_ray + self.step_x * x + self.step_y * y
    }

    /// The planes each tile of the tile rows `tile_rows` can see.
    fn tile_planes(&self, tile_rows: std::ops::Range<usize>) -> TilePlanes {
        let columns = self.width.div_ceil(TILE);
        let [inverse_fx, inverse_fy] = self.inverse_focal;
        // The camera-frame cone of the tile's pixels, ± the margin, along
        // one axis: `first` is the tile's first pixel, `corner` the ray's
        // coordinate at pixel 0.
        let span = |first: usize, corner: f64, inverse: f64| {
            let low = first as f64 - TILE_MARGIN;
            let high = (first + TILE - 1) as f64 + TILE_MARGIN;
            [corner + low * inverse, corner + high * inverse]
        };
        let mut tiles = TilePlanes {
            first_tile_row: tile_rows.start,
            columns,
            ends: Vec::with_capacity(tile_rows.len() * columns),
            planes: Vec::new(),
        };
        for tile_row in tile_rows {
            let ys = span(tile_row * TILE, self.corner_ray_camera.y, inverse_fy);
            for column in 0..columns {
                let xs = span(column * TILE, self.corner_ray_camera.x, inverse_fx);
                let reached = self.visible.iter().enumerate();
                tiles.planes.extend(
                    reached
                        .filter(|(_, v)| v.reaches(xs, ys))
                        .map(|(index, _)| index as u32),
                );
                tiles.ends.push(tiles.planes.len());
            }
        }
        tiles
    }

    /// Which plane (or [`SKY`]) each pixel corner of rows
    /// `first_row..first_row + rows` sees: `(rows + 1) × (width + 1)` ids.
    /// A corner is cast among the planes of the pixel below and right of
    /// it (the last pixel for the last row and column).
    fn corner_ids(&self, first_row: usize, rows: usize, tiles: &TilePlanes) -> Vec<u32> {
        let mut ids = Vec::with_capacity((rows + 1) * (self.width + 1));
        for row in 0..=rows {
            let pixel_row = (first_row + row).min(self.height - 1);
            let y = (first_row + row) as f64 - 0.5;
            for column in 0..=self.width {
                let ray = self.ray(column as f64 - 0.5, y);
                let planes = tiles.at(column.min(self.width - 1), pixel_row);
                ids.push(
                    self.intersect(&ray, planes)
                        .map_or(SKY, |h| h.visible as u32),
                );
            }
        }
        ids
    }

    /// The mean of 4×4 samples spread over the pixel, cast among `planes`.
    fn supersample(&self, x: f64, y: f64, planes: &[u32]) -> f64 {
        let mut sum = 0.0;
        for dy in SUBSAMPLES {
            for dx in SUBSAMPLES {
                let ray = self.ray(x + dx, y + dy);
                let hit = self.intersect(&ray, planes);
                sum += self.shade(&ray, hit.as_ref(), 0.25);
            }
        }
        sum / 16.0
    }

    /// The nearest front-side plane along `ray` among the visible planes
    /// `planes` (in increasing order, so ties go to the earlier plane).
    fn intersect(&self, ray: &Vector3<f64>, planes: &[u32]) -> Option<RayHit> {
        let mut best: Option<RayHit> = None;
        for &index in planes {
            if let Some(hit) = self.intersect_plane(index as usize, ray) {
                if best.is_none_or(|b| hit.t < b.t) {
                    best = Some(hit);
                }
            }
        }
        best
    }

    /// Where `ray` meets visible plane `index` from the front, if it does.
    fn intersect_plane(&self, index: usize, ray: &Vector3<f64>) -> Option<RayHit> {
        let visible = &self.visible[index];
        let denom = visible.normal.dot(ray);
        if denom >= 0.0 {
            return None;
        }
        let t = visible.offset / denom;
        if t <= 0.0 {
            return None;
        }
        let rel = visible.eye_from_origin + ray * t;
        let plane = visible.plane;
        let u = rel.dot(&plane.u_axis);
        let v = rel.dot(&plane.v_axis);
        plane.contains(u, v).then_some(RayHit {
            visible: index,
            t,
            u,
            v,
            denom,
        })
    }

    /// The gray level seen along `ray`, box-filtered over a footprint of
    /// `scale` pixels.
    fn shade(&self, ray: &Vector3<f64>, hit: Option<&RayHit>, scale: f64) -> f64 {
        let Some(hit) = hit else {
            return self.world.sky(ray);
        };
        // Ray differentials: how far the hit moves on the plane per pixel.
        let visible = &self.visible[hit.visible];
        let plane = visible.plane;
        let moved = |step: &Vector3<f64>| -> Vector3<f64> {
            (step - ray * (visible.normal.dot(step) / hit.denom)) * (hit.t * scale)
        };
        let (along_x, along_y) = (moved(&self.step_x), moved(&self.step_y));
        let footprint = Footprint {
            du: along_x.dot(&plane.u_axis).abs() + along_y.dot(&plane.u_axis).abs(),
            dv: along_x.dot(&plane.v_axis).abs() + along_y.dot(&plane.v_axis).abs(),
        };
        plane.texture.sample(hit.u, hit.v, footprint)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::synthetic::texture::Texture;

    fn wall_at(z: f64, gray: f64) -> World {
        World::new(vec![Plane::new(
            Point3::new(-50.0, 50.0, z),
            Vector3::x(),
            -Vector3::y(),
            100.0,
            100.0,
            Texture::Flat { gray },
        )])
    }

    #[test]
    fn a_fronto_parallel_wall_has_constant_depth() {
        let camera = StereoCamera::centred(64, 48, 50.0, 0.5);
        let view = render_view(
            &wall_at(7.0, 80.0),
            &camera,
            &Isometry3::identity(),
            true,
            3,
        );
        assert!(view.gray.iter().all(|&g| g == 80.0));
        assert!(view.depth.iter().all(|&z| (z - 7.0).abs() < 1e-5));
    }

    #[test]
    fn the_sky_has_no_depth_and_threads_do_not_change_the_image() {
        let camera = StereoCamera::centred(64, 48, 50.0, 0.5);
        let behind = Isometry3::translation(0.0, 0.0, 10.0);
        let view = render_view(&wall_at(7.0, 80.0), &camera, &behind, true, 2);
        assert!(view.depth.iter().all(|&z| z == 0.0));
        let one = render_view(
            &wall_at(7.0, 80.0),
            &camera,
            &Isometry3::identity(),
            false,
            1,
        );
        let many = render_view(
            &wall_at(7.0, 80.0),
            &camera,
            &Isometry3::identity(),
            false,
            5,
        );
        assert_eq!(one, many);
        assert!(one.depth.is_empty());
    }

    #[test]
    fn tiles_keep_every_plane_a_ray_can_hit() {
        // Many small boards all around (some behind, some straddling the
        // camera plane), one tilted camera: every ray the renderer casts
        // (pixel corners, centres, sub-samples) finds among its tile's
        // planes exactly the hit it finds among all planes.
        let mut rng = crate::dataset::synthetic::SplitMix64::new(7);
        let mut planes = Vec::new();
        for _ in 0..150 {
            let origin = Point3::new(
                rng.uniform(-30.0, 30.0),
                rng.uniform(-10.0, 10.0),
                rng.uniform(-20.0, 60.0),
            );
            let u = Vector3::new(rng.normal(), rng.normal(), rng.normal());
            let v = u.cross(&Vector3::new(rng.normal(), rng.normal(), rng.normal()));
            let (a, b) = (rng.uniform(0.05, 6.0), rng.uniform(0.05, 6.0));
            planes.push(Plane::new(origin, u, v, a, b, Texture::Flat { gray: 9.0 }));
        }
        let world = World::new(planes);
        let camera = StereoCamera::centred(83, 61, 40.0, 0.5);
        let pose = Isometry3::new(Vector3::new(0.3, -0.2, 0.1), Vector3::new(0.1, 0.4, -0.05));
        let setup = ViewSetup::new(&world, &camera, &pose);
        let all: Vec<u32> = (0..setup.visible.len() as u32).collect();
        let tiles = setup.tile_planes(0..camera.height.div_ceil(TILE));
        assert!(tiles.planes.len() < all.len() * tiles.ends.len() / 2);
        let (mut hits, mut checked) = (0, 0);
        for y in 0..camera.height {
            for x in 0..camera.width {
                let offsets = [-0.5, -0.375, 0.0, 0.375, 0.5];
                for dy in offsets {
                    for dx in offsets {
                        let ray = setup.ray(x as f64 + dx, y as f64 + dy);
                        let expected = setup.intersect(&ray, &all);
                        assert_eq!(setup.intersect(&ray, tiles.at(x, y)), expected);
                        hits += usize::from(expected.is_some());
                        checked += 1;
                    }
                }
            }
        }
        assert!(hits > 5000, "{hits} hits of {checked} rays");
    }
}
