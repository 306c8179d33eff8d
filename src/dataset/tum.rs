//! TUM RGB-D sequences: `rgb.txt`, `depth.txt` (`timestamp filename`, `#`
//! comments) and `groundtruth.txt`, with rgb/depth associated by timestamp.

use std::path::{Path, PathBuf};

use super::associate::associate;
use super::error::{DatasetError, Result};
use super::text::{data_lines, parse_f64, read_text, require_dir};

/// `associate.py`'s default tolerance between rgb and depth timestamps (s).
pub const DEFAULT_MAX_DIFFERENCE: f64 = 0.02;

/// An associated colour/depth pair.
#[derive(Debug, Clone, PartialEq)]
pub struct RgbdFrame {
    /// Time of the colour image (s).
    pub timestamp: f64,
    /// Path of the colour image.
    pub rgb: PathBuf,
    /// Time of the depth image (s).
    pub depth_timestamp: f64,
    /// Path of the depth image.
    pub depth: PathBuf,
}

/// A TUM RGB-D sequence with associated frames.
#[derive(Debug, Clone)]
pub struct TumRgbdSequence {
    dir: PathBuf,
    frames: Vec<RgbdFrame>,
    unmatched_rgb: usize,
    unmatched_depth: usize,
    ground_truth: Option<PathBuf>,
}

/// One row of `rgb.txt` or `depth.txt`.
struct ListedImage {
    t: f64,
    path: PathBuf,
}

impl TumRgbdSequence {
    /// Opens a sequence folder and associates `rgb.txt` with `depth.txt`,
    /// pairing images whose timestamps differ by less than `max_difference`
    /// seconds (see [`DEFAULT_MAX_DIFFERENCE`]); images left without a
    /// partner are dropped. Listed image files must exist.
    pub fn open(dir: impl AsRef<Path>, max_difference: f64) -> Result<Self> {
        let dir = require_dir(dir.as_ref())?;
        let rgb = read_list(&dir, "rgb.txt")?;
        let depth = read_list(&dir, "depth.txt")?;
        let rgb_t: Vec<f64> = rgb.iter().map(|i| i.t).collect();
        let depth_t: Vec<f64> = depth.iter().map(|i| i.t).collect();
        let frames: Vec<RgbdFrame> = associate(&rgb_t, &depth_t, max_difference)
            .into_iter()
            .map(|a| RgbdFrame {
                timestamp: rgb[a.first].t,
                rgb: rgb[a.first].path.clone(),
                depth_timestamp: depth[a.second].t,
                depth: depth[a.second].path.clone(),
            })
            .collect();
        if frames.is_empty() {
            return Err(DatasetError::NoFrames { path: dir });
        }
        let gt = dir.join("groundtruth.txt");
        Ok(Self {
            unmatched_rgb: rgb.len() - frames.len(),
            unmatched_depth: depth.len() - frames.len(),
            frames,
            ground_truth: gt.is_file().then_some(gt),
            dir,
        })
    }

    /// The sequence folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Associated frames, sorted by colour timestamp.
    pub fn frames(&self) -> &[RgbdFrame] {
        &self.frames
    }

    /// Number of colour images dropped for want of a depth partner.
    pub fn unmatched_rgb(&self) -> usize {
        self.unmatched_rgb
    }

    /// Number of depth images dropped for want of a colour partner.
    pub fn unmatched_depth(&self) -> usize {
        self.unmatched_depth
    }

    /// `groundtruth.txt`, when it exists.
    pub fn ground_truth_path(&self) -> Option<PathBuf> {
        self.ground_truth.clone()
    }
}

/// Reads a `timestamp filename` list, checking that each file exists.
fn read_list(dir: &Path, name: &str) -> Result<Vec<ListedImage>> {
    let path = dir.join(name);
    let text = read_text(&path)?;
    let mut out = Vec::new();
    for line in data_lines(&text) {
        let mut fields = line.text.split_whitespace();
        let (Some(t), Some(file)) = (fields.next(), fields.next()) else {
            return Err(DatasetError::row(
                &path,
                line.number,
                "expected `timestamp filename`",
            ));
        };
        let t = parse_f64(&path, line.number, "timestamp", t)?;
        let image = dir.join(file);
        if !image.is_file() {
            return Err(DatasetError::MissingFile { path: image });
        }
        out.push(ListedImage { t, path: image });
    }
    Ok(out)
}
