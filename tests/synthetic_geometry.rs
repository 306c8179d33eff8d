//! The synthetic renderer's geometry against exact ground truth: markers at
//! known 3-D points land where K and T_wc project them, stereo disparity is
//! f·b/Z, and depth maps agree with the planes and between the cameras.

use nalgebra::{Isometry3, Point2, Point3, Translation3, UnitQuaternion, Vector3};
use spslam::dataset::synthetic::{
    render_view, DiscMarker, Plane, SceneName, StereoCamera, SyntheticConfig, SyntheticSequence,
    Texture, View, World,
};

const BACKGROUND: f64 = 40.0;
const MARKER: f64 = 230.0;

/// A wall 6 m ahead (z = 6, facing the camera) with white discs at known
/// (u, v), over a floor, with a second wall 9 m ahead to the right.
fn marker_world() -> (World, Vec<Point3<f64>>) {
    let discs: Vec<DiscMarker> = [(5.0, 5.0), (3.5, 4.0), (6.5, 6.0), (4.0, 6.3), (6.2, 3.8)]
        .iter()
        .map(|&(u, v)| DiscMarker {
            u,
            v,
            radius: 0.12,
            gray: MARKER,
        })
        .collect();
    let wall = Plane::new(
        Point3::new(-5.0, 5.0, 6.0),
        Vector3::x(),
        -Vector3::y(),
        10.0,
        10.0,
        Texture::Markers {
            background: BACKGROUND,
            discs: discs.clone(),
        },
    );
    let points = discs.iter().map(|d| wall.point(d.u, d.v)).collect();
    let far = Plane::new(
        Point3::new(5.0, 5.0, 9.0),
        Vector3::x(),
        -Vector3::y(),
        10.0,
        10.0,
        Texture::Flat { gray: 120.0 },
    );
    let floor = Plane::new(
        Point3::new(-20.0, 3.0, -5.0),
        Vector3::x(),
        Vector3::z(),
        40.0,
        40.0,
        Texture::Flat { gray: 90.0 },
    );
    (World::new(vec![wall, far, floor]), points)
}

fn camera() -> StereoCamera {
    StereoCamera::centred(640, 480, 400.0, 0.5)
}

/// Poses that look at the marker wall from several places and angles.
fn poses() -> Vec<Isometry3<f64>> {
    vec![
        Isometry3::identity(),
        Isometry3::from_parts(
            Translation3::new(0.4, -0.3, 1.0),
            UnitQuaternion::from_euler_angles(0.03, 0.12, -0.05),
        ),
        Isometry3::from_parts(
            Translation3::new(-1.0, 0.2, -0.5),
            UnitQuaternion::from_euler_angles(-0.06, -0.2, 0.1),
        ),
    ]
}

/// Intensity-weighted centroid of `gray − background` in a window around `guess`.
fn centroid(view: &View, guess: Point2<f64>, half: i64) -> Point2<f64> {
    let (mut sx, mut sy, mut sw) = (0.0, 0.0, 0.0);
    let (gx, gy) = (guess.x.round() as i64, guess.y.round() as i64);
    for y in gy - half..=gy + half {
        for x in gx - half..=gx + half {
            assert!(
                (0..view.width as i64).contains(&x) && (0..view.height as i64).contains(&y),
                "marker window leaves the image at ({x}, {y})"
            );
            let g = view.gray[y as usize * view.width + x as usize] as f64;
            let w = (g - BACKGROUND).max(0.0);
            sx += w * x as f64;
            sy += w * y as f64;
            sw += w;
        }
    }
    assert!(sw > 0.0, "no marker near {guess}");
    Point2::new(sx / sw, sy / sw)
}

/// The same view quantised to 8 bits, as written to PNG.
fn quantised(view: &View) -> View {
    let mut q = view.clone();
    q.gray
        .iter_mut()
        .for_each(|g| *g = g.round().clamp(0.0, 255.0));
    q
}

#[test]
fn markers_project_where_the_ground_truth_pose_says() {
    let (world, points) = marker_world();
    let cam = camera();
    let mut worst: f64 = 0.0;
    for pose in poses() {
        let view = quantised(&render_view(&world, &cam, &pose, false, 0));
        for point in &points {
            let in_camera = pose.inverse() * point;
            let expected = cam.project(&in_camera).expect("marker in front");
            let radius_px = 0.12 * cam.fx / in_camera.z;
            let found = centroid(&view, expected, radius_px.ceil() as i64 + 4);
            let error = (found - expected).norm();
            worst = worst.max(error);
            assert!(
                error < 0.1,
                "marker at {point}: found {found}, expected {expected}"
            );
        }
    }
    println!("marker centroid vs projection: worst error {worst:.4} px");
}

#[test]
fn stereo_disparity_is_f_b_over_z() {
    let (world, points) = marker_world();
    let cam = camera();
    let mut worst: f64 = 0.0;
    for pose in poses() {
        let left = quantised(&render_view(&world, &cam, &pose, false, 0));
        let right = quantised(&render_view(&world, &cam, &cam.right_pose(&pose), false, 0));
        for point in &points {
            let in_left = pose.inverse() * point;
            let guess = cam.project(&in_left).expect("marker in front");
            let half = (0.12 * cam.fx / in_left.z).ceil() as i64 + 4;
            let expected_disparity = cam.fx * cam.baseline / in_left.z;
            let l = centroid(&left, guess, half);
            let r = centroid(
                &right,
                guess - nalgebra::Vector2::new(expected_disparity, 0.0),
                half,
            );
            assert!((l.y - r.y).abs() < 0.05, "rows differ: {l} vs {r}");
            let error = (l.x - r.x - expected_disparity).abs();
            worst = worst.max(error);
            assert!(
                error < 0.1,
                "disparity {} vs f·b/Z = {expected_disparity}",
                l.x - r.x
            );
        }
    }
    println!("disparity vs f·b/Z: worst error {worst:.4} px");
}

#[test]
fn depth_is_the_analytic_plane_depth() {
    let (world, _) = marker_world();
    let cam = camera();
    for pose in poses() {
        let view = render_view(&world, &cam, &pose, true, 0);
        let eye = Point3::from(pose.translation.vector);
        let mut checked = 0;
        for y in (0..cam.height).step_by(7) {
            for x in (0..cam.width).step_by(7) {
                let z = view.depth[y * cam.width + x] as f64;
                let ray = pose.rotation * cam.ray(x as f64, y as f64);
                // The analytic depth: the nearest plane along the pixel's ray.
                let expected = world
                    .planes
                    .iter()
                    .filter_map(|p| {
                        let n = p.normal();
                        let t = n.dot(&(p.origin - eye)) / n.dot(&ray);
                        let on = eye + ray * t - p.origin;
                        let (u, v) = (on.dot(&p.u_axis), on.dot(&p.v_axis));
                        (t > 0.0 && n.dot(&ray) < 0.0 && p.contains(u, v)).then_some(t)
                    })
                    .fold(f64::INFINITY, f64::min);
                if expected.is_finite() {
                    assert!(
                        (z - expected).abs() < 1e-5 * expected,
                        "({x}, {y}): {z} vs {expected}"
                    );
                    checked += 1;
                } else {
                    assert_eq!(z, 0.0, "sky at ({x}, {y}) must have no depth");
                }
            }
        }
        assert!(checked > 5000, "{checked} pixels checked");
    }
}

#[test]
fn left_and_right_depth_maps_agree_through_the_disparity() {
    let sequence =
        SyntheticSequence::new(SyntheticConfig::for_scene(SceneName::Loop).noiseless()).unwrap();
    let cam = *sequence.camera();
    let pose = sequence.pose(40);
    let left = render_view(sequence.world(), &cam, &pose, true, 0);
    let right = render_view(sequence.world(), &cam, &cam.right_pose(&pose), true, 0);
    let (mut agree, mut total) = (0usize, 0usize);
    for y in (0..cam.height).step_by(3) {
        for x in (0..cam.width).step_by(3) {
            let z = left.depth[y * cam.width + x] as f64;
            if z <= 0.0 {
                continue;
            }
            let xr = x as f64 - cam.fx * cam.baseline / z;
            if xr < 0.0 || xr > (cam.width - 1) as f64 {
                continue;
            }
            total += 1;
            let zr = right.depth[y * cam.width + xr.round() as usize] as f64;
            // Rounding xr moves along the surface by < ½ pixel.
            if (zr - z).abs() < 0.02 * z {
                agree += 1;
            }
        }
    }
    let share = agree as f64 / total as f64;
    println!(
        "left/right depth agreement: {agree}/{total} ({:.2}%)",
        100.0 * share
    );
    // The rest are occlusions and depth edges.
    assert!(share > 0.97, "{agree}/{total}");
}
