//! The camera's rotation between two frames from their whole images, for a
//! turn too fast for the motion model.
//!
//! PTAM's small blurry images (Klein and Murray, "Improving the agility of
//! keyframe-based SLAM", ECCV 2008, section 4): each frame is shrunk to a
//! thumbnail of about 80 pixels across and blurred, and the rotation that
//! maps the last frame's thumbnail onto this one is found by image
//! alignment, with no features at all. Motion blur, which smears the
//! keypoints and their descriptors, barely changes a thumbnail that is
//! blurred anyway, and the alignment is not fooled by a repeated texture
//! the way descriptor matching is. PTAM aligns the two thumbnails with a
//! 2-D rigid motion and turns it into a rotation; here the rotation itself
//! is estimated (the warp of a pure rotation, `K·R·K⁻¹`), from the better of
//! two starts: the motion model's rotation and the best whole-pixel shift
//! of the half-size thumbnails.
//!
//! The rotation is only a prediction: tracking searches the last frame's
//! points around it, and its own inliers decide, as for the motion model.

use nalgebra::{Matrix3, UnitQuaternion, Vector2, Vector3};

use crate::features::GrayImageView;
use crate::optim::lie::so3_exp;
use crate::optim::reprojection::PinholeStereo;

/// The thumbnail's longest side at most, pixels.
const THUMBNAIL_SIDE: usize = 80;
/// The Gaussian blur of the thumbnail, thumbnail pixels.
const THUMBNAIL_BLUR_SIGMA: f32 = 1.0;
/// The fraction of each side searched for the coarse shift, either way.
const SHIFT_SEARCH_FRACTION: f64 = 0.3;
/// Gauss-Newton iterations at most.
const MAX_ITERATIONS: usize = 15;
/// Huber threshold on the residual of normalised intensities.
const HUBER_DELTA: f64 = 0.5;
/// The fraction of the last thumbnail that must land inside this one.
const MIN_OVERLAP: f64 = 0.4;

/// A frame's image shrunk and blurred, its intensities normalised to zero
/// mean and unit variance (so a change of exposure does not count), with
/// the camera's intrinsics at its scale.
#[derive(Debug, Clone, PartialEq)]
pub struct SmallBlurryImage {
    width: usize,
    height: usize,
    pixels: Vec<f32>,
    /// Focal lengths and principal point in thumbnail pixels.
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
}

/// The rotation found between two thumbnails.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageRotation {
    /// `R_cl`: from the last frame's camera to this frame's.
    pub rotation: UnitQuaternion<f64>,
    /// Root mean square residual of the normalised intensities, at the end.
    pub rms: f64,
    /// The fraction of the last thumbnail's pixels that land in this one.
    pub overlap: f64,
    /// The correlation of the two thumbnails' intensities over that
    /// overlap (1: the same view; two unrelated views score far lower).
    pub correlation: f64,
}

impl SmallBlurryImage {
    /// The thumbnail of `image` taken with `camera`; `None` for an image
    /// smaller than 8 pixels either way or of one intensity (a black frame).
    pub fn new(image: GrayImageView<'_>, camera: &PinholeStereo) -> Option<Self> {
        let (w, h) = (image.width(), image.height());
        if w < 8 || h < 8 {
            return None;
        }
        let factor = w.max(h).div_ceil(THUMBNAIL_SIDE).max(1);
        let (width, height) = (w / factor, h / factor);
        if width < 4 || height < 4 {
            return None;
        }
        let mut pixels = vec![0f32; width * height];
        let norm = 1.0 / (factor * factor) as f32;
        for ty in 0..height {
            for y in ty * factor..(ty + 1) * factor {
                let row = image.row(y);
                for (tx, out) in pixels[ty * width..(ty + 1) * width].iter_mut().enumerate() {
                    let sum: u32 = row[tx * factor..(tx + 1) * factor]
                        .iter()
                        .map(|&v| u32::from(v))
                        .sum();
                    *out += sum as f32 * norm;
                }
            }
        }
        let pixels = gaussian_blur(&pixels, width, height, THUMBNAIL_BLUR_SIGMA);
        let pixels = normalised(pixels)?;
        // Pixel centres: thumbnail pixel i covers full pixels
        // [i·f, (i+1)·f), whose centre is i·f + (f − 1)/2.
        let f = factor as f64;
        let offset = (f - 1.0) / 2.0;
        Some(Self {
            width,
            height,
            pixels,
            fx: camera.fx / f,
            fy: camera.fy / f,
            cx: (camera.cx - offset) / f,
            cy: (camera.cy - offset) / f,
        })
    }

    /// The thumbnail's size, pixels.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    fn at(&self, x: usize, y: usize) -> f32 {
        self.pixels[y * self.width + x]
    }

    fn bearing(&self, x: f64, y: f64) -> Vector3<f64> {
        Vector3::new((x - self.cx) / self.fx, (y - self.cy) / self.fy, 1.0)
    }

    /// Bilinear intensity and gradient at `(x, y)`, or `None` outside the
    /// interior (one pixel from the border).
    fn sample(&self, x: f64, y: f64) -> Option<(f64, Vector2<f64>)> {
        if !(x >= 1.0 && y >= 1.0 && x < (self.width - 2) as f64 && y < (self.height - 2) as f64) {
            return None;
        }
        let (x0, y0) = (x.floor() as usize, y.floor() as usize);
        let (ax, ay) = (x - x0 as f64, y - y0 as f64);
        let v = |xx: usize, yy: usize| f64::from(self.at(xx, yy));
        let value_at = |xx: usize, yy: usize| {
            (1.0 - ay) * ((1.0 - ax) * v(xx, yy) + ax * v(xx + 1, yy))
                + ay * ((1.0 - ax) * v(xx, yy + 1) + ax * v(xx + 1, yy + 1))
        };
        let value = value_at(x0, y0);
        let gx =
            (1.0 - ay) * (v(x0 + 1, y0) - v(x0, y0)) + ay * (v(x0 + 1, y0 + 1) - v(x0, y0 + 1));
        let gy =
            (1.0 - ax) * (v(x0, y0 + 1) - v(x0, y0)) + ax * (v(x0 + 1, y0 + 1) - v(x0 + 1, y0));
        Some((value, Vector2::new(gx, gy)))
    }
}

/// The rotation `R_cl` that maps `last`'s thumbnail onto `current`'s, from
/// the better of `start` (the motion model's rotation) and the best shift
/// of the half-size thumbnails; `None` when the thumbnails differ in size
/// or too little of `last` lands in `current` whichever start is taken.
pub fn estimate_rotation(
    last: &SmallBlurryImage,
    current: &SmallBlurryImage,
    start: &UnitQuaternion<f64>,
) -> Option<ImageRotation> {
    if last.size() != current.size() {
        return None;
    }
    let mut starts = vec![*start];
    if let Some(shifted) = best_shift_rotation(last, current) {
        starts.push(shifted);
    }
    starts
        .into_iter()
        .filter_map(|s| refine(last, current, s))
        .filter(|r| r.overlap >= MIN_OVERLAP)
        .min_by(|a, b| a.rms.total_cmp(&b.rms))
}

/// Gauss-Newton with Huber weights on `R_cl` (left perturbation), the
/// gradient taken in `current` at each warped pixel of `last`; a step that
/// raises the cost is halved, up to three times, then the search stops.
fn refine(
    last: &SmallBlurryImage,
    current: &SmallBlurryImage,
    start: UnitQuaternion<f64>,
) -> Option<ImageRotation> {
    let (mut best, mut h, mut g) = normal_equations(last, current, &start)?;
    for _ in 0..MAX_ITERATIONS {
        let Some(mut step) = h.cholesky().map(|c| c.solve(&(-g))) else {
            break;
        };
        let mut improved = None;
        for _ in 0..4 {
            let rotation = so3_exp(&step) * best.rotation;
            if let Some(next) = normal_equations(last, current, &rotation) {
                if next.0.rms < best.rms {
                    improved = Some(next);
                    break;
                }
            }
            step *= 0.5;
        }
        let Some(next) = improved else {
            break;
        };
        (best, h, g) = next;
        if step.norm() < 1e-6 {
            break;
        }
    }
    Some(best)
}

/// The robust cost of `rotation` (as an [`ImageRotation`]) with the
/// Gauss-Newton normal equations `H·δ = −g` for a left perturbation
/// `exp(δ)·R`; `None` when fewer than 16 pixels of `last` land inside
/// `current`. The intensities of `current` are first mapped onto `last`'s
/// by the gain and offset that fit the overlap best (least squares): each
/// thumbnail was normalised over its own view, and the two views differ.
fn normal_equations(
    last: &SmallBlurryImage,
    current: &SmallBlurryImage,
    rotation: &UnitQuaternion<f64>,
) -> Option<(ImageRotation, Matrix3<f64>, Vector3<f64>)> {
    let r: Matrix3<f64> = rotation.to_rotation_matrix().into_inner();
    // (value in current, its Jacobian row for δ, the value in last).
    let mut samples: Vec<(f64, Vector3<f64>, f64)> = Vec::with_capacity(last.pixels.len());
    for y in 0..last.height {
        for x in 0..last.width {
            let p = r * last.bearing(x as f64, y as f64);
            if p.z <= 1e-6 {
                continue;
            }
            let iz = 1.0 / p.z;
            let (u, v) = (
                current.fx * p.x * iz + current.cx,
                current.fy * p.y * iz + current.cy,
            );
            let Some((value, grad)) = current.sample(u, v) else {
                continue;
            };
            // d(u,v)/dp, and dp/dδ = −[p]× for p ← exp(δ)·p; a row vector
            // times −[p]× is p × row.
            let du = Vector3::new(current.fx * iz, 0.0, -current.fx * p.x * iz * iz);
            let dv = Vector3::new(0.0, current.fy * iz, -current.fy * p.y * iz * iz);
            let j = p.cross(&(grad.x * du + grad.y * dv));
            samples.push((value, j, f64::from(last.at(x, y))));
        }
    }
    if samples.len() < 16 {
        return None;
    }
    let fit = fit_intensities(&samples);
    let (gain, offset) = (fit.gain, fit.offset);
    let mut h = Matrix3::<f64>::zeros();
    let mut g = Vector3::<f64>::zeros();
    let mut cost = 0.0;
    for (value, j, target) in &samples {
        let residual = gain * value + offset - target;
        let abs = residual.abs();
        let (weight, rho) = if abs <= HUBER_DELTA {
            (1.0, residual * residual)
        } else {
            (HUBER_DELTA / abs, HUBER_DELTA * (2.0 * abs - HUBER_DELTA))
        };
        cost += rho;
        let j = gain * j;
        h += weight * j * j.transpose();
        g += weight * residual * j;
    }
    let found = ImageRotation {
        rotation: *rotation,
        rms: (cost / samples.len() as f64).sqrt(),
        overlap: samples.len() as f64 / last.pixels.len() as f64,
        correlation: fit.correlation,
    };
    Some((found, h, g))
}

/// How one set of intensities maps onto another.
struct IntensityFit {
    gain: f64,
    offset: f64,
    correlation: f64,
}

/// The least-squares `(gain, offset)` with `gain·value + offset ≈ target`,
/// and the correlation of the two; `(1, 0)` and no correlation when either
/// does not vary.
fn fit_intensities(samples: &[(f64, Vector3<f64>, f64)]) -> IntensityFit {
    let n = samples.len() as f64;
    let (mut sx, mut sy, mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (x, _, y) in samples {
        sx += x;
        sy += y;
        sxx += x * x;
        syy += y * y;
        sxy += x * y;
    }
    let (var_x, var_y) = (sxx - sx * sx / n, syy - sy * sy / n);
    let cov = sxy - sx * sy / n;
    if var_x <= 1e-9 || var_y <= 1e-9 {
        return IntensityFit {
            gain: 1.0,
            offset: 0.0,
            correlation: 0.0,
        };
    }
    let gain = cov / var_x;
    IntensityFit {
        gain,
        offset: (sy - gain * sx) / n,
        correlation: cov / (var_x * var_y).sqrt(),
    }
}

/// The rotation taking the principal ray to the ray through the best
/// whole-pixel shift of the half-size thumbnails (mean squared difference
/// over the overlap, which must cover half of the image).
fn best_shift_rotation(
    last: &SmallBlurryImage,
    current: &SmallBlurryImage,
) -> Option<UnitQuaternion<f64>> {
    let (a, w, h) = half_size(&last.pixels, last.width, last.height);
    let (b, _, _) = half_size(&current.pixels, current.width, current.height);
    let range_x = (w as f64 * SHIFT_SEARCH_FRACTION).round() as isize;
    let range_y = (h as f64 * SHIFT_SEARCH_FRACTION).round() as isize;
    let (wi, hi) = (w as isize, h as isize);
    let mut best: Option<(f64, isize, isize)> = None;
    for dy in -range_y..=range_y {
        for dx in -range_x..=range_x {
            let (x0, x1) = ((-dx).max(0), (wi - dx).min(wi));
            let (y0, y1) = ((-dy).max(0), (hi - dy).min(hi));
            let count = (x1 - x0).max(0) * (y1 - y0).max(0);
            if 2 * count < wi * hi {
                continue;
            }
            let mut sum = 0.0f64;
            for y in y0..y1 {
                let row_a = &a[(y * wi) as usize..((y + 1) * wi) as usize];
                let row_b = &b[((y + dy) * wi) as usize..((y + dy + 1) * wi) as usize];
                for x in x0..x1 {
                    let d = f64::from(row_b[(x + dx) as usize] - row_a[x as usize]);
                    sum += d * d;
                }
            }
            let score = sum / count as f64;
            if best.is_none_or(|(s, _, _)| score < s) {
                best = Some((score, dx, dy));
            }
        }
    }
    let (_, dx, dy) = best?;
    // A shift of the half-size image is twice that in the thumbnail.
    let (cx, cy) = (last.cx, last.cy);
    let from = last.bearing(cx, cy);
    let to = last.bearing(cx + 2.0 * dx as f64, cy + 2.0 * dy as f64);
    UnitQuaternion::rotation_between(&from, &to).or(Some(UnitQuaternion::identity()))
}

/// Every 2×2 block averaged.
fn half_size(pixels: &[f32], width: usize, height: usize) -> (Vec<f32>, usize, usize) {
    let (w, h) = (width / 2, height / 2);
    let mut out = vec![0f32; w * h];
    for y in 0..h {
        for x in 0..w {
            let p = |xx: usize, yy: usize| pixels[yy * width + xx];
            out[y * w + x] = 0.25
                * (p(2 * x, 2 * y)
                    + p(2 * x + 1, 2 * y)
                    + p(2 * x, 2 * y + 1)
                    + p(2 * x + 1, 2 * y + 1));
        }
    }
    (out, w, h)
}

/// Separable Gaussian blur with clamped borders.
fn gaussian_blur(pixels: &[f32], width: usize, height: usize, sigma: f32) -> Vec<f32> {
    let radius = (3.0 * sigma).ceil() as isize;
    let kernel: Vec<f32> = (-radius..=radius)
        .map(|i| (-((i * i) as f32) / (2.0 * sigma * sigma)).exp())
        .collect();
    let total: f32 = kernel.iter().sum();
    let kernel: Vec<f32> = kernel.iter().map(|k| k / total).collect();
    let clamp = |v: isize, n: usize| v.clamp(0, n as isize - 1) as usize;
    let mut rows = vec![0f32; pixels.len()];
    for y in 0..height {
        for x in 0..width {
            rows[y * width + x] = kernel
                .iter()
                .enumerate()
                .map(|(k, w)| {
                    w * pixels[y * width + clamp(x as isize + k as isize - radius, width)]
                })
                .sum();
        }
    }
    let mut out = vec![0f32; pixels.len()];
    for y in 0..height {
        for x in 0..width {
            out[y * width + x] = kernel
                .iter()
                .enumerate()
                .map(|(k, w)| w * rows[clamp(y as isize + k as isize - radius, height) * width + x])
                .sum();
        }
    }
    out
}

/// Zero mean, unit variance; `None` for a flat image.
fn normalised(mut pixels: Vec<f32>) -> Option<Vec<f32>> {
    let n = pixels.len() as f64;
    let mean = pixels.iter().map(|&v| f64::from(v)).sum::<f64>() / n;
    let var = pixels
        .iter()
        .map(|&v| (f64::from(v) - mean).powi(2))
        .sum::<f64>()
        / n;
    if var < 1e-6 {
        return None;
    }
    let scale = 1.0 / var.sqrt();
    for v in &mut pixels {
        *v = ((f64::from(*v) - mean) * scale) as f32;
    }
    Some(pixels)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::features::GrayImage;

    /// An image of a texture painted on the sphere of directions, seen by
    /// a camera rotated by `r_cw`: any two such images are related by a
    /// pure rotation, exactly.
    fn sphere_image(
        camera: &PinholeStereo,
        w: usize,
        h: usize,
        r_cw: &UnitQuaternion<f64>,
    ) -> GrayImage {
        let r_wc = r_cw.inverse();
        let mut data = vec![0u8; w * h];
        for y in 0..h {
            for x in 0..w {
                let b = Vector3::new(
                    (x as f64 - camera.cx) / camera.fx,
                    (y as f64 - camera.cy) / camera.fy,
                    1.0,
                )
                .normalize();
                let d = r_wc * b;
                let t = (7.0 * d.x + 3.0 * d.y).sin()
                    + (11.0 * d.y - 5.0 * d.z).cos()
                    + 0.7 * (23.0 * d.x * d.z + 13.0 * d.y).sin()
                    + 0.5 * (31.0 * d.z + 17.0 * d.x).cos();
                data[y * w + x] = (128.0 + 40.0 * t).clamp(0.0, 255.0) as u8;
            }
        }
        GrayImage::from_vec(data, w, h).unwrap()
    }

    fn angle_between(a: &UnitQuaternion<f64>, b: &UnitQuaternion<f64>) -> f64 {
        (a.inverse() * b).angle().to_degrees()
    }

    #[test]
    fn a_pure_rotation_is_found_from_the_motion_models_start_or_without_one() {
        let camera = PinholeStereo::new(400.0, 400.0, 319.5, 239.5, 0.0);
        let last_rotation = UnitQuaternion::identity();
        let last = sphere_image(&camera, 640, 480, &last_rotation);
        let last_sbi = SmallBlurryImage::new(last.view(), &camera).unwrap();
        assert_eq!(last_sbi.size(), (80, 60));
        // Yaw of up to 12° a frame (the blurred lap's corners turn 11.5°),
        // with some pitch and roll.
        for (yaw, pitch, roll) in [
            (12.0f64, 0.0f64, 0.0f64),
            (-9.0, 2.0, 1.0),
            (4.0, -3.0, -2.0),
        ] {
            let r_cl = UnitQuaternion::from_euler_angles(
                pitch.to_radians(),
                yaw.to_radians(),
                roll.to_radians(),
            );
            let current = sphere_image(&camera, 640, 480, &r_cl);
            let sbi = SmallBlurryImage::new(current.view(), &camera).unwrap();
            let found = estimate_rotation(&last_sbi, &sbi, &UnitQuaternion::identity()).unwrap();
            let error = angle_between(&found.rotation, &r_cl);
            // Measured 0.013–0.024°; a thumbnail pixel is 1.15° here.
            assert!(
                error < 0.1,
                "yaw {yaw}, pitch {pitch}, roll {roll}: {error:.3}° off (rms {:.3})",
                found.rms
            );
        }
    }

    #[test]
    fn a_change_of_exposure_does_not_move_the_rotation() {
        let camera = PinholeStereo::new(400.0, 400.0, 319.5, 239.5, 0.0);
        let last = sphere_image(&camera, 320, 240, &UnitQuaternion::identity());
        let r_cl = UnitQuaternion::from_euler_angles(0.0, 0.1, 0.0);
        let current = sphere_image(&camera, 320, 240, &r_cl);
        let dimmed: Vec<u8> = current.as_slice().iter().map(|&v| v / 2 + 10).collect();
        let dimmed = GrayImage::from_vec(dimmed, 320, 240).unwrap();
        let a = SmallBlurryImage::new(last.view(), &camera).unwrap();
        let b = SmallBlurryImage::new(dimmed.view(), &camera).unwrap();
        let found = estimate_rotation(&a, &b, &UnitQuaternion::identity()).unwrap();
        assert!(angle_between(&found.rotation, &r_cl) < 0.1);
    }

    #[test]
    fn unrelated_views_align_with_a_low_correlation() {
        let camera = PinholeStereo::new(400.0, 400.0, 319.5, 239.5, 0.0);
        let a = sphere_image(&camera, 640, 480, &UnitQuaternion::identity());
        // The texture seen from behind: another place.
        let b = sphere_image(
            &camera,
            640,
            480,
            &UnitQuaternion::from_euler_angles(0.0, 3.0, 0.0),
        );
        let (a, b) = (
            SmallBlurryImage::new(a.view(), &camera).unwrap(),
            SmallBlurryImage::new(b.view(), &camera).unwrap(),
        );
        let same = estimate_rotation(&a, &a, &UnitQuaternion::identity()).unwrap();
        assert!(same.correlation > 0.999, "{}", same.correlation);
        if let Some(other) = estimate_rotation(&a, &b, &UnitQuaternion::identity()) {
            eprintln!("unrelated views: correlation {:.3}", other.correlation);
            assert!(other.correlation < 0.8, "{}", other.correlation);
        }
    }

    #[test]
    fn a_black_frame_has_no_thumbnail() {
        let camera = PinholeStereo::new(400.0, 400.0, 159.5, 119.5, 0.0);
        let black = GrayImage::from_vec(vec![0; 320 * 240], 320, 240).unwrap();
        assert!(SmallBlurryImage::new(black.view(), &camera).is_none());
    }
}
