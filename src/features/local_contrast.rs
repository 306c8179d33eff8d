//! Local contrast (the standard deviation of the gray levels in a square
//! window) at many points of one image: the periodic filter's low-contrast
//! rejection ([`super::periodic::reject_low_contrast`]).
//!
//! Summed directly, one point costs its window's area, `(2r+1)²`: 81 pixels
//! at the default radius 4, but 4,225 at the largest allowed (32), and a
//! KITTI image's thousands of candidates would then read the image dozens
//! of times over. [`ContrastWindows`] switches to summed-area tables (one
//! pass over the image, then four reads a point) where those would cost
//! less. Both ways add the same integers exactly, so they give bit-for-bit
//! the same contrast.

use super::GrayImageView;

/// A window's pixel count, sum and sum of squares.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct WindowSums {
    count: u64,
    sum: u64,
    sum_squares: u64,
}

impl WindowSums {
    /// The standard deviation of the window's gray levels (0 for no pixel).
    fn standard_deviation(self) -> f32 {
        if self.count == 0 {
            return 0.0;
        }
        let n = self.count as f64;
        let mean = self.sum as f64 / n;
        ((self.sum_squares as f64 / n - mean * mean).max(0.0)).sqrt() as f32
    }
}

/// The (2r+1)² window around (x, y), clipped to a `width × height` image:
/// columns `x0..x1`, rows `y0..y1`.
fn window(x: usize, y: usize, radius: usize, width: usize, height: usize) -> [usize; 4] {
    let x0 = x.saturating_sub(radius).min(width);
    let y0 = y.saturating_sub(radius).min(height);
    let x1 = x.saturating_add(radius).saturating_add(1).min(width);
    let y1 = y.saturating_add(radius).saturating_add(1).min(height);
    [x0, y0, x1.max(x0), y1.max(y0)]
}

/// Sums the window pixel by pixel.
fn direct_sums(image: GrayImageView<'_>, x: usize, y: usize, radius: usize) -> WindowSums {
    let [x0, y0, x1, y1] = window(x, y, radius, image.width(), image.height());
    let mut sums = WindowSums {
        count: ((x1 - x0) * (y1 - y0)) as u64,
        sum: 0,
        sum_squares: 0,
    };
    for row_index in y0..y1 {
        for &p in &image.row(row_index)[x0..x1] {
            sums.sum += u64::from(p);
            sums.sum_squares += u64::from(p) * u64::from(p);
        }
    }
    sums
}

/// Standard deviation of the gray levels in the (2r+1)² window around
/// (x, y), clipped to the image.
pub fn local_contrast(image: GrayImageView<'_>, x: usize, y: usize, radius: usize) -> f32 {
    direct_sums(image, x, y, radius).standard_deviation()
}

/// Summed-area tables of the gray levels and of their squares, with a
/// leading row and column of zeros: entry `(y, x)` sums the pixels above
/// and left of pixel `(y, x)`.
struct SummedAreaTables {
    stride: usize,
    width: usize,
    height: usize,
    sum: Vec<u64>,
    sum_squares: Vec<u64>,
}

impl SummedAreaTables {
    /// One pass over `image`.
    fn new(image: GrayImageView<'_>) -> Self {
        let (width, height) = (image.width(), image.height());
        let stride = width + 1;
        let mut sum = vec![0u64; stride * (height + 1)];
        let mut sum_squares = vec![0u64; stride * (height + 1)];
        for y in 0..height {
            let (mut row_sum, mut row_squares) = (0u64, 0u64);
            for (x, &p) in image.row(y).iter().enumerate() {
                row_sum += u64::from(p);
                row_squares += u64::from(p) * u64::from(p);
                let at = (y + 1) * stride + x + 1;
                sum[at] = sum[at - stride] + row_sum;
                sum_squares[at] = sum_squares[at - stride] + row_squares;
            }
        }
        Self {
            stride,
            width,
            height,
            sum,
            sum_squares,
        }
    }

    /// The window's sums from four entries of each table.
    fn sums(&self, x: usize, y: usize, radius: usize) -> WindowSums {
        let [x0, y0, x1, y1] = window(x, y, radius, self.width, self.height);
        let rectangle = |table: &[u64]| {
            let at = |row: usize, column: usize| table[row * self.stride + column];
            at(y1, x1) + at(y0, x0) - at(y0, x1) - at(y1, x0)
        };
        WindowSums {
            count: ((x1 - x0) * (y1 - y0)) as u64,
            sum: rectangle(&self.sum),
            sum_squares: rectangle(&self.sum_squares),
        }
    }
}

/// How [`ContrastWindows`] sums its windows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum ContrastMethod {
    /// Pixel by pixel.
    Direct,
    /// From summed-area tables.
    SummedArea,
}

impl ContrastMethod {
    /// The cheaper way for `points` windows of radius `radius` on a
    /// `width × height` image: direct sums read `(2r+1)²` pixels a point;
    /// the tables cost about two passes over the image (building both)
    /// and a few reads a point.
    pub(crate) fn cheaper(points: usize, radius: usize, width: usize, height: usize) -> Self {
        let side = radius.saturating_mul(2).saturating_add(1);
        let direct = points.saturating_mul(side.saturating_mul(side));
        let tables = width
            .saturating_add(1)
            .saturating_mul(height.saturating_add(1))
            .saturating_mul(2)
            .saturating_add(points.saturating_mul(8));
        if direct > tables {
            Self::SummedArea
        } else {
            Self::Direct
        }
    }
}

/// Local contrast at many points of one image with one radius.
pub(crate) struct ContrastWindows<'a> {
    image: GrayImageView<'a>,
    radius: usize,
    tables: Option<SummedAreaTables>,
}

impl<'a> ContrastWindows<'a> {
    /// Prepares `method` (the tables are built here when it needs them).
    pub(crate) fn new(image: GrayImageView<'a>, radius: usize, method: ContrastMethod) -> Self {
        let tables = (method == ContrastMethod::SummedArea).then(|| SummedAreaTables::new(image));
        Self {
            image,
            radius,
            tables,
        }
    }

    /// The standard deviation of the gray levels around (x, y), as
    /// [`local_contrast`] gives it.
    pub(crate) fn at(&self, x: usize, y: usize) -> f32 {
        match &self.tables {
            Some(tables) => tables.sums(x, y, self.radius),
            None => direct_sums(self.image, x, y, self.radius),
        }
        .standard_deviation()
    }
}

#[cfg(test)]
mod tests {
    use super::{local_contrast, ContrastMethod, ContrastWindows};
    use crate::features::GrayImageView;
    use proptest::prelude::*;

    proptest! {
        /// The tables give bit for bit what the direct sums give, at every
        /// point (borders and out-of-image points included) and radius.
        #[test]
        fn summed_area_tables_equal_direct_sums(
            width in 1usize..40,
            height in 1usize..40,
            padding in 0usize..3,
            seed in any::<u64>(),
            radius in 0usize..33,
            points in proptest::collection::vec((0usize..45, 0usize..45), 1..20),
        ) {
            let stride = width + padding;
            let mut state = seed | 1;
            let data: Vec<u8> = (0..stride * height)
                .map(|_| {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    (state >> 56) as u8
                })
                .collect();
            let image = GrayImageView::new(&data, width, height, stride).expect("a valid view");
            let tables = ContrastWindows::new(image, radius, ContrastMethod::SummedArea);
            let direct = ContrastWindows::new(image, radius, ContrastMethod::Direct);
            for (x, y) in points {
                let expected = local_contrast(image, x, y, radius);
                prop_assert_eq!(tables.at(x, y).to_bits(), expected.to_bits());
                prop_assert_eq!(direct.at(x, y).to_bits(), expected.to_bits());
            }
        }
    }

    #[test]
    fn the_tables_are_chosen_only_where_windows_would_reread_the_image() {
        // The default radius on a KITTI image's candidates: direct.
        assert_eq!(
            ContrastMethod::cheaper(8_000, 4, 1226, 370),
            ContrastMethod::Direct
        );
        // The largest radius there: 8,000 × 4,225 pixels against two passes.
        assert_eq!(
            ContrastMethod::cheaper(8_000, 32, 1226, 370),
            ContrastMethod::SummedArea
        );
        // A few points: direct at any radius.
        assert_eq!(
            ContrastMethod::cheaper(3, 32, 1226, 370),
            ContrastMethod::Direct
        );
    }
}
