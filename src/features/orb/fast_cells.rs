//! FAST corners on a grid of ~35-px cells of one pyramid level, as
//! ORB-SLAM3's `ComputeKeyPointsOctTree` detects them.

use opencv::core::{KeyPoint, Mat, Rect, Vector};
use opencv::prelude::*;

use crate::features::FeatureError;

/// ORB-SLAM3's `EDGE_THRESHOLD`: no keypoint is searched closer than
/// `EDGE_THRESHOLD - 3` px to a level's border.
pub const EDGE_THRESHOLD: i32 = 19;
/// ORB-SLAM3's target cell side, in level pixels.
const CELL_SIDE: f32 = 35.0;

/// A FAST corner in level coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FastCorner {
    /// Column in level pixels.
    pub x: f32,
    /// Row in level pixels.
    pub y: f32,
    /// FAST score.
    pub response: f32,
}

/// The region searched on a level: `[min_x, max_x) x [min_y, max_y)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SearchRegion {
    /// First column.
    pub min_x: i32,
    /// One past the last column.
    pub max_x: i32,
    /// First row.
    pub min_y: i32,
    /// One past the last row.
    pub max_y: i32,
}

impl SearchRegion {
    /// ORB-SLAM3's borders for a level of `cols` x `rows` pixels.
    pub fn for_level(cols: i32, rows: i32) -> Self {
        Self {
            min_x: EDGE_THRESHOLD - 3,
            min_y: EDGE_THRESHOLD - 3,
            max_x: cols - EDGE_THRESHOLD + 3,
            max_y: rows - EDGE_THRESHOLD + 3,
        }
    }

    /// Width in pixels (may be <= 0 for tiny levels).
    pub fn width(&self) -> i32 {
        self.max_x - self.min_x
    }

    /// Height in pixels (may be <= 0 for tiny levels).
    pub fn height(&self) -> i32 {
        self.max_y - self.min_y
    }
}

/// FAST with non-maximum suppression on each cell (cells overlap by 6 px, so
/// FAST's 3-px margin does not leave gaps); a cell with no corner at
/// `ini_threshold` is searched again at `min_threshold`. Corners are returned
/// relative to the region's top-left corner, as ORB-SLAM3 hands them to
/// `DistributeOctTree`.
pub fn detect_fast_in_cells(
    level: &Mat,
    region: SearchRegion,
    ini_threshold: i32,
    min_threshold: i32,
) -> Result<Vec<FastCorner>, FeatureError> {
    let (width, height) = (region.width() as f32, region.height() as f32);
    let n_cols = (width / CELL_SIDE) as i32;
    let n_rows = (height / CELL_SIDE) as i32;
    if n_cols < 1 || n_rows < 1 {
        return Ok(Vec::new());
    }
    let cell_w = (width / n_cols as f32).ceil() as i32;
    let cell_h = (height / n_rows as f32).ceil() as i32;
    let mut corners = Vec::new();
    let mut found = Vector::<KeyPoint>::new();
    for i in 0..n_rows {
        let ini_y = region.min_y + i * cell_h;
        if ini_y >= region.max_y - 3 {
            continue;
        }
        let max_y = (ini_y + cell_h + 6).min(region.max_y);
        for j in 0..n_cols {
            let ini_x = region.min_x + j * cell_w;
            if ini_x >= region.max_x - 6 {
                continue;
            }
            let max_x = (ini_x + cell_w + 6).min(region.max_x);
            let cell = Mat::roi(level, Rect::new(ini_x, ini_y, max_x - ini_x, max_y - ini_y))?;
            opencv::features2d::fast(&cell, &mut found, ini_threshold, true)?;
            if found.is_empty() {
                opencv::features2d::fast(&cell, &mut found, min_threshold, true)?;
            }
            corners.extend(found.iter().map(|kp| FastCorner {
                x: kp.pt().x + (j * cell_w) as f32,
                y: kp.pt().y + (i * cell_h) as f32,
                response: kp.response(),
            }));
        }
    }
    Ok(corners)
}
