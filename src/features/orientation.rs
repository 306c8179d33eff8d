//! Keypoint orientation by the intensity centroid, as ORB-SLAM3's `IC_Angle`.

use super::GrayImageView;

/// ORB-SLAM3's `HALF_PATCH_SIZE`.
pub const HALF_PATCH_SIZE: usize = 15;
/// ORB-SLAM3's `PATCH_SIZE`.
pub const PATCH_SIZE: usize = 31;

/// The circular patch's half-widths per row (ORB-SLAM3's `umax`).
#[derive(Clone, Debug)]
pub struct CircularPatch {
    umax: Vec<i32>,
}

impl Default for CircularPatch {
    fn default() -> Self {
        Self::new()
    }
}

impl CircularPatch {
    /// Builds `umax` exactly as ORB-SLAM3's extractor constructor does.
    pub fn new() -> Self {
        let hp = HALF_PATCH_SIZE as i32;
        let mut umax = vec![0i32; HALF_PATCH_SIZE + 2];
        let half_sqrt2 = HALF_PATCH_SIZE as f32 * std::f32::consts::SQRT_2 / 2.0;
        let vmax = (half_sqrt2 + 1.0).floor() as i32;
        let vmin = half_sqrt2.ceil() as i32;
        let hp2 = (hp * hp) as f64;
        for v in 0..=vmax {
            umax[v as usize] = (hp2 - (v * v) as f64).sqrt().round() as i32;
        }
        let mut v0 = 0usize;
        let mut v = hp;
        while v >= vmin {
            while umax[v0] == umax[v0 + 1] {
                v0 += 1;
            }
            umax[v as usize] = v0 as i32;
            v0 += 1;
            v -= 1;
        }
        Self { umax }
    }

    /// The orientation in degrees, [0, 360), of the intensity centroid around
    /// (x, y). Pixels of the patch outside the image are skipped.
    ///
    /// Each row's part inside the image is summed as one slice (the pixels,
    /// and the pixels times their column offset) in 32-bit integers, which
    /// cannot overflow (31 pixels of at most 255, times offsets of at most
    /// 15); the moments are the exact integers of the per-pixel loop.
    pub fn angle(&self, image: GrayImageView<'_>, x: f32, y: f32) -> f32 {
        let (cx, cy) = (x.round() as i64, y.round() as i64);
        let (w, h) = (image.width() as i64, image.height() as i64);
        let (mut m01, mut m10) = (0i64, 0i64);
        let hp = HALF_PATCH_SIZE as i64;
        for v in -hp..=hp {
            let py = cy + v;
            if py < 0 || py >= h {
                continue;
            }
            let d = self.umax[v.unsigned_abs() as usize] as i64;
            let (first, last) = ((cx - d).max(0), (cx + d).min(w - 1));
            if first > last {
                continue;
            }
            let row = &image.row(py as usize)[first as usize..=last as usize];
            let (mut sum, mut weighted) = (0i32, 0i32);
            for (p, u) in row.iter().zip((first - cx) as i32..) {
                let p = i32::from(*p);
                sum += p;
                weighted += u * p;
            }
            m10 += i64::from(weighted);
            m01 += v * i64::from(sum);
        }
        let deg = (m01 as f32).atan2(m10 as f32).to_degrees();
        if deg < 0.0 {
            deg + 360.0
        } else {
            deg
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn umax_matches_orb_slam3() {
        // Values printed by ORB-SLAM3's constructor for HALF_PATCH_SIZE = 15.
        let p = CircularPatch::new();
        assert_eq!(
            &p.umax[..16],
            &[15, 15, 15, 15, 14, 14, 14, 13, 13, 12, 11, 10, 9, 8, 6, 3]
        );
    }

    /// ORB-SLAM3's `IC_Angle` pixel by pixel, skipping pixels outside the image.
    fn angle_pixel_by_pixel(
        patch: &CircularPatch,
        image: GrayImageView<'_>,
        x: f32,
        y: f32,
    ) -> f32 {
        let (cx, cy) = (x.round() as i64, y.round() as i64);
        let (w, h) = (image.width() as i64, image.height() as i64);
        let (mut m01, mut m10) = (0i64, 0i64);
        let hp = HALF_PATCH_SIZE as i64;
        for v in -hp..=hp {
            let d = patch.umax[v.unsigned_abs() as usize] as i64;
            for u in -d..=d {
                let (px, py) = (cx + u, cy + v);
                if px < 0 || px >= w || py < 0 || py >= h {
                    continue;
                }
                let p = image.row(py as usize)[px as usize] as i64;
                m10 += u * p;
                m01 += v * p;
            }
        }
        let deg = (m01 as f32).atan2(m10 as f32).to_degrees();
        if deg < 0.0 {
            deg + 360.0
        } else {
            deg
        }
    }

    #[test]
    fn row_sums_equal_the_pixel_by_pixel_moments_everywhere_including_the_borders() {
        let (w, h) = (57usize, 41usize);
        let mut state = 12345u32;
        let pixels: Vec<u8> = (0..w * h)
            .map(|_| {
                state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                (state >> 24) as u8
            })
            .collect();
        let img = GrayImageView::new(&pixels, w, h, w).unwrap();
        let patch = CircularPatch::new();
        for yi in -3..h as i32 + 3 {
            for xi in -3..w as i32 + 3 {
                let (x, y) = (xi as f32 + 0.3, yi as f32 - 0.2);
                assert_eq!(
                    patch.angle(img, x, y).to_bits(),
                    angle_pixel_by_pixel(&patch, img, x, y).to_bits(),
                    "at ({x}, {y})"
                );
            }
        }
        let white = vec![255u8; 64 * 64];
        let img = GrayImageView::new(&white, 64, 64, 64).unwrap();
        assert_eq!(
            patch.angle(img, 20.0, 40.0).to_bits(),
            angle_pixel_by_pixel(&patch, img, 20.0, 40.0).to_bits()
        );
    }

    #[test]
    fn a_bright_right_half_points_at_zero_degrees_and_bottom_at_ninety() {
        let right: Vec<u8> = (0..64 * 64)
            .map(|i| if i % 64 >= 32 { 200 } else { 10 })
            .collect();
        let img = GrayImageView::new(&right, 64, 64, 64).unwrap();
        let a = CircularPatch::new().angle(img, 32.0, 32.0);
        assert!(!(5.0..=355.0).contains(&a), "angle {a}");
        let bottom: Vec<u8> = (0..64 * 64)
            .map(|i| if i / 64 >= 32 { 200 } else { 10 })
            .collect();
        let img = GrayImageView::new(&bottom, 64, 64, 64).unwrap();
        let a = CircularPatch::new().angle(img, 32.0, 32.0);
        assert!((a - 90.0).abs() < 5.0, "angle {a}");
    }
}
