//! The patch check of ORB-SLAM3's `ComputeStereoMatches`: an 11x11 SAD on the
//! level images (each patch minus its centre value), slid along the row,
//! with a parabola through the minimum for sub-pixel precision; plus the
//! periodic guard on the same curve.

use crate::features::GrayImageView;

use super::PeriodicGuard;

/// Why a patch refinement failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SadFailure {
    /// A patch would leave the image.
    Border,
    /// The minimum is at the end of the search window.
    WindowEdge,
    /// The parabola's vertex is more than one pixel from the minimum.
    SubPixelOutOfRange,
    /// The curve dips as deep one period away.
    Periodic,
}

/// The refined match on the level image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SadFit {
    /// Right column on the level image, sub-pixel.
    pub right_x: f32,
    /// The SAD at the best integer offset.
    pub sad: f32,
}

/// One refinement: the left patch centred at (`left_x`, `y`), the right one
/// starting at `right_x` (all on the level images, integer pixels).
pub struct SadSearch<'a> {
    /// Left level image.
    pub left: GrayImageView<'a>,
    /// Right level image.
    pub right: GrayImageView<'a>,
    /// Patch half-size.
    pub half: usize,
    /// Offsets tried: -radius..=radius.
    pub radius: usize,
    /// The periodic guard, if any.
    pub periodic: Option<PeriodicGuard>,
}

impl SadSearch<'_> {
    /// Runs the search; see the module docs.
    pub fn refine(&self, left_x: i64, y: i64, right_x: i64) -> Result<SadFit, SadFailure> {
        let half = self.half as i64;
        let radius = self.radius as i64;
        let inside = |img: GrayImageView<'_>, x: i64| {
            x - half >= 0
                && x + half < img.width() as i64
                && y - half >= 0
                && y + half < img.height() as i64
        };
        if !inside(self.left, left_x)
            || !inside(self.right, right_x - radius)
            || !inside(self.right, right_x + radius)
        {
            return Err(SadFailure::Border);
        }
        let curve: Vec<f32> = (-radius..=radius)
            .map(|o| self.sad(left_x, y, right_x + o))
            .collect();
        let mut best = 0usize;
        for (i, &v) in curve.iter().enumerate() {
            if v < curve[best] {
                best = i;
            }
        }
        if best == 0 || best == curve.len() - 1 {
            return Err(SadFailure::WindowEdge);
        }
        let (d1, d2, d3) = (curve[best - 1], curve[best], curve[best + 1]);
        let denom = 2.0 * (d1 + d3 - 2.0 * d2);
        let delta = if denom > 0.0 { (d1 - d3) / denom } else { 0.0 };
        if !(-1.0..=1.0).contains(&delta) {
            return Err(SadFailure::SubPixelOutOfRange);
        }
        let best_offset = best as i64 - radius;
        if let Some(guard) = self.periodic {
            if self.dips_one_period_away(left_x, y, right_x + best_offset, d2, &curve, guard) {
                return Err(SadFailure::Periodic);
            }
        }
        Ok(SadFit {
            right_x: (right_x + best_offset) as f32 + delta,
            sad: d2,
        })
    }

    /// True when the SAD one period left or right of `best_x` (±tolerance)
    /// comes down to within `1 - sad_depth_ratio` of the best dip, the depth
    /// measured from the median of the search curve. Offsets outside the
    /// image are ignored.
    fn dips_one_period_away(
        &self,
        left_x: i64,
        y: i64,
        best_x: i64,
        best_sad: f32,
        curve: &[f32],
        guard: PeriodicGuard,
    ) -> bool {
        let mut sorted = curve.to_vec();
        sorted.sort_by(f32::total_cmp);
        let reference = sorted[sorted.len() / 2];
        let depth = reference - best_sad;
        if depth <= 0.0 {
            return true; // a flat curve has no distinct minimum
        }
        let half = self.half as i64;
        let tol = guard.tolerance.round() as i64;
        for sign in [-1i64, 1] {
            let centre = best_x + sign * guard.period.round() as i64;
            let mut alt = f32::INFINITY;
            for x in centre - tol..=centre + tol {
                if x - half >= 0 && x + half < self.right.width() as i64 {
                    alt = alt.min(self.sad(left_x, y, x));
                }
            }
            if reference - alt >= guard.sad_depth_ratio * depth {
                return true;
            }
        }
        false
    }

    /// ORB-SLAM3's SAD: both patches minus their centre pixel, L1 norm.
    fn sad(&self, left_x: i64, y: i64, right_x: i64) -> f32 {
        let half = self.half as i64;
        let lc = self.left.get(left_x as usize, y as usize) as i32;
        let rc = self.right.get(right_x as usize, y as usize) as i32;
        let mut sum = 0i64;
        for dy in -half..=half {
            let lrow = self.left.row((y + dy) as usize);
            let rrow = self.right.row((y + dy) as usize);
            let l = &lrow[(left_x - half) as usize..=(left_x + half) as usize];
            let r = &rrow[(right_x - half) as usize..=(right_x + half) as usize];
            for (a, b) in l.iter().zip(r) {
                sum += ((*a as i32 - lc) - (*b as i32 - rc)).abs() as i64;
            }
        }
        sum as f32
    }
}
