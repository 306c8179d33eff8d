//! Ray casting: for each pixel centre, the nearest plane hit gives the gray
//! level (box-filtered over the pixel's footprint on the surface, from ray
//! differentials) and the depth Z in the camera frame.

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

/// A plane with the per-view quantities of the intersection precomputed.
struct Visible<'a> {
    plane: &'a Plane,
    normal: Vector3<f64>,
    /// `normal · (origin − eye)`: negative for a plane seen from the front.
    offset: f64,
    /// `eye − origin`.
    eye_from_origin: Vector3<f64>,
}

/// Per-view constants shared by every row.
struct ViewSetup<'a> {
    world: &'a World,
    visible: Vec<Visible<'a>>,
    /// Ray of the pixel (0, 0) in the world frame (camera z = 1).
    corner_ray: Vector3<f64>,
    /// Change of the ray per pixel along x and y.
    step_x: Vector3<f64>,
    step_y: Vector3<f64>,
    width: usize,
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
    let eye = Point3::from(pose_wc.translation.vector);
    let rotation = pose_wc.rotation.to_rotation_matrix();
    let visible = world
        .planes
        .iter()
        .filter(|p| p.faces(&eye))
        .map(|plane| {
            let normal = plane.normal();
            Visible {
                plane,
                normal,
                offset: normal.dot(&(plane.origin - eye)),
                eye_from_origin: eye - plane.origin,
            }
        })
        .collect();
    let setup = ViewSetup {
        world,
        visible,
        corner_ray: rotation * camera.ray(0.0, 0.0),
        step_x: rotation * Vector3::new(1.0 / camera.fx, 0.0, 0.0),
        step_y: rotation * Vector3::new(0.0, 1.0 / camera.fy, 0.0),
        width,
    };
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

impl ViewSetup<'_> {
    /// Renders the rows starting at `first_row` into the given slices.
    fn render_rows(&self, first_row: usize, gray: &mut [f32], mut depth: Option<&mut [f32]>) {
        for (row_offset, gray_row) in gray.chunks_mut(self.width).enumerate() {
            let y = (first_row + row_offset) as f64;
            let row_ray = self.corner_ray + self.step_y * y;
            for (x, pixel) in gray_row.iter_mut().enumerate() {
                let ray = row_ray + self.step_x * x as f64;
                let (value, z) = self.shade(&ray);
                *pixel = value as f32;
                if let Some(depth) = depth.as_deref_mut() {
                    depth[row_offset * self.width + x] = z as f32;
                }
            }
        }
    }

    /// Gray level and depth (0 for the sky) along one pixel ray.
    fn shade(&self, ray: &Vector3<f64>) -> (f64, f64) {
        let mut best: Option<(&Visible, f64, f64, f64, f64)> = None;
        let mut best_t = f64::INFINITY;
        for visible in &self.visible {
            let denom = visible.normal.dot(ray);
            if denom >= 0.0 {
                continue;
            }
            let t = visible.offset / denom;
            if t <= 0.0 || t >= best_t {
                continue;
            }
            let rel = visible.eye_from_origin + ray * t;
            let plane = visible.plane;
            let u = rel.dot(&plane.u_axis);
            let v = rel.dot(&plane.v_axis);
            if plane.contains(u, v) {
                best_t = t;
                best = Some((visible, t, u, v, denom));
            }
        }
        let Some((visible, t, u, v, denom)) = best else {
            return (self.world.sky(ray), 0.0);
        };
        // Ray differentials: how far the hit moves on the plane per pixel.
        let plane = visible.plane;
        let moved = |step: &Vector3<f64>| -> Vector3<f64> {
            (step - ray * (visible.normal.dot(step) / denom)) * t
        };
        let (along_x, along_y) = (moved(&self.step_x), moved(&self.step_y));
        let footprint = Footprint {
            du: along_x.dot(&plane.u_axis).abs() + along_y.dot(&plane.u_axis).abs(),
            dv: along_x.dot(&plane.v_axis).abs() + along_y.dot(&plane.v_axis).abs(),
        };
        (plane.texture.sample(u, v, footprint), t)
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
}
