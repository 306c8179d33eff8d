//! The input sequence of `spslam run` and how its frames are read. A frame
//! that cannot be used comes back as an [`Unreadable`]: the image at fault
//! and the cause, so that the run can skip it and say why.

use std::path::{Path, PathBuf};

use anyhow::{bail, Result};
use opencv::core::{Mat, MatTraitConst};
use opencv::imgcodecs;
use spslam::dataset::{StereoFrame, StereoRectifier};
use spslam::eval::{read_euroc, read_kitti, Trajectory};
use spslam::features::{FeatureError, GrayImage};
use spslam::settings::SlamSettings;

use super::euroc_layout::EurocLayout;
use super::kitti_layout::KittiLayout;

/// Why an input image cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum UnreadableCause {
    /// The file is not there.
    #[error("no such file")]
    Missing,
    /// The file is there but does not decode to an image.
    #[error("cannot be decoded: {0}")]
    Undecodable(String),
    /// The image's size differs from the first frame's.
    #[error(
        "the image is {width}x{height}, the first frame's images are {expected_width}x{expected_height}"
    )]
    SizeChanged {
        /// Its width.
        width: usize,
        /// Its height.
        height: usize,
        /// The first frame's width.
        expected_width: usize,
        /// The first frame's height.
        expected_height: usize,
    },
    /// The right image's size differs from the left one's.
    #[error("the left image is {left_width}x{left_height}, this right one is {right_width}x{right_height}")]
    StereoSizeMismatch {
        /// Left width.
        left_width: usize,
        /// Left height.
        left_height: usize,
        /// Right width.
        right_width: usize,
        /// Right height.
        right_height: usize,
    },
    /// A raw EuRoC image whose size is not the calibration's.
    #[error(
        "the image is {width}x{height}, the calibration's is {expected_width}x{expected_height}"
    )]
    CalibrationSize {
        /// Its width.
        width: i32,
        /// Its height.
        height: i32,
        /// The calibration's width.
        expected_width: i32,
        /// The calibration's height.
        expected_height: i32,
    },
    /// Rectification failed on the pair.
    #[error("rectification failed: {0}")]
    Rectification(String),
    /// Feature extraction rejected the pair.
    #[error("feature extraction failed on the stereo pair: {0}")]
    Features(String),
}

/// An input frame that cannot be used: the image at fault and the cause.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}: {cause}", .path.display())]
pub struct Unreadable {
    /// The image at fault (the left one when the pair as a whole is).
    pub path: PathBuf,
    /// What is wrong with it.
    pub cause: UnreadableCause,
}

impl Unreadable {
    fn new(path: &Path, cause: UnreadableCause) -> Self {
        Self {
            path: path.to_path_buf(),
            cause,
        }
    }
}

/// A stereo sequence and how to read its images.
pub enum Source {
    /// KITTI or a synthetic sequence in KITTI's layout.
    Kitti(Box<KittiLayout>),
    /// An EuRoC ASL folder, rectified on reading.
    Euroc(EurocLayout),
}

impl Source {
    /// Opens `kitti:DIR`, `euroc:DIR` or `synth:DIR`.
    pub fn open(spec: &str) -> Result<Self> {
        let Some((kind, dir)) = spec.split_once(':') else {
            bail!("--dataset `{spec}` is not KIND:DIR (kitti:, euroc: or synth:)");
        };
        let dir = PathBuf::from(dir);
        match kind {
            "kitti" | "synth" => Ok(Self::Kitti(Box::new(KittiLayout::open(&dir)?))),
            "euroc" => Ok(Self::Euroc(EurocLayout::open(&dir)?)),
            other => bail!("unknown dataset kind `{other}` (kitti, euroc or synth)"),
        }
    }

    /// Every frame of the sequence.
    pub fn frames(&self) -> &[StereoFrame] {
        match self {
            Self::Kitti(seq) => &seq.frames,
            Self::Euroc(seq) => &seq.frames,
        }
    }

    /// Whether the sequence is in KITTI's layout (KITTI or synthetic).
    pub fn is_kitti(&self) -> bool {
        matches!(self, Self::Kitti(_))
    }

    /// Settings from the calibration: KITTI's P0/P1, EuRoC's rectified
    /// camera. Every stereo depth is kept (no `Tracking.maxDepth`): points
    /// beyond `ThDepth` are ORB-SLAM3's "far" points, tracked and optimised
    /// like the others.
    pub fn default_settings(&self) -> SlamSettings {
        match self {
            Self::Kitti(seq) => {
                let c = &seq.calibration;
                SlamSettings::rectified_stereo(c.fx, c.fy, c.cx, c.cy, c.baseline)
            }
            Self::Euroc(seq) => {
                let r = &seq.rectifier;
                let mut s =
                    SlamSettings::rectified_stereo(r.fx(), r.fy(), r.cx(), r.cy(), r.baseline());
                s.camera.fps = 20.0;
                s
            }
        }
    }

    /// The image size of the first frame of `frames` that can be read, to
    /// size the camera rig. An error when none can.
    pub fn first_size(&self, frames: &[StereoFrame]) -> Result<(usize, usize)> {
        let mut first_error = None;
        for (index, frame) in frames.iter().enumerate() {
            match self.load(frame, None) {
                Ok((left, _)) => return Ok((left.width(), left.height())),
                Err(e) => {
                    first_error.get_or_insert((index, e));
                }
            }
        }
        match first_error {
            Some((index, e)) => {
                bail!("no frame of the sequence can be read (frame {index}: {e})")
            }
            None => bail!("the sequence has no frames"),
        }
    }

    /// Reads (and for EuRoC rectifies) a frame's pair. With `expected`,
    /// both images must have that size (the first frame's).
    pub fn load(
        &self,
        frame: &StereoFrame,
        expected: Option<(usize, usize)>,
    ) -> std::result::Result<(GrayImage, GrayImage), Unreadable> {
        let (left, right) = match self {
            Self::Kitti(_) => (read_gray(&frame.left)?, read_gray(&frame.right)?),
            Self::Euroc(seq) => read_rectified(&seq.rectifier, frame)?,
        };
        let size = |image: &GrayImage| (image.width(), image.height());
        if let Some((expected_width, expected_height)) = expected {
            let (width, height) = size(&left);
            if (width, height) != (expected_width, expected_height) {
                return Err(Unreadable::new(
                    &frame.left,
                    UnreadableCause::SizeChanged {
                        width,
                        height,
                        expected_width,
                        expected_height,
                    },
                ));
            }
        }
        if size(&left) != size(&right) {
            return Err(Unreadable::new(
                &frame.right,
                UnreadableCause::StereoSizeMismatch {
                    left_width: left.width(),
                    left_height: left.height(),
                    right_width: right.width(),
                    right_height: right.height(),
                },
            ));
        }
        Ok((left, right))
    }

    /// The ground truth of the first `rows` frames (KITTI layout), or all
    /// of it (EuRoC, paired by timestamp); `None` without ground truth.
    pub fn ground_truth(&self, rows: usize) -> Result<Option<Trajectory>> {
        match self {
            Self::Kitti(seq) => {
                let Some(path) = &seq.ground_truth else {
                    return Ok(None);
                };
                let gt = read_kitti(path)?;
                let n = rows.min(gt.len());
                Ok(Some(gt.select(&(0..n).collect::<Vec<_>>())))
            }
            Self::Euroc(seq) => match &seq.ground_truth {
                Some(path) => Ok(Some(read_euroc(path)?)),
                None => Ok(None),
            },
        }
    }
}

/// Reads one image as gray.
fn read_gray(path: &Path) -> std::result::Result<GrayImage, Unreadable> {
    if !path.is_file() {
        return Err(Unreadable::new(path, UnreadableCause::Missing));
    }
    GrayImage::load(path).map_err(|e| {
        let reason = match e {
            FeatureError::ImageRead { reason, .. } => reason,
            other => other.to_string(),
        };
        Unreadable::new(path, UnreadableCause::Undecodable(reason))
    })
}

/// Reads one raw EuRoC image and checks it against the calibration's size.
fn read_raw(path: &Path, rectifier: &StereoRectifier) -> std::result::Result<Mat, Unreadable> {
    let undecodable = |reason: String| Unreadable::new(path, UnreadableCause::Undecodable(reason));
    if !path.is_file() {
        return Err(Unreadable::new(path, UnreadableCause::Missing));
    }
    let text = path
        .to_str()
        .ok_or_else(|| undecodable("the path is not valid UTF-8".into()))?;
    let mat = imgcodecs::imread(text, imgcodecs::IMREAD_GRAYSCALE)
        .map_err(|e| undecodable(e.to_string()))?;
    if mat.empty() {
        return Err(undecodable(
            "OpenCV could not decode it (unknown format or corrupt file)".into(),
        ));
    }
    let got = mat.size().map_err(|e| undecodable(e.to_string()))?;
    let (expected_width, expected_height) = rectifier.image_size();
    if (got.width, got.height) != (expected_width, expected_height) {
        return Err(Unreadable::new(
            path,
            UnreadableCause::CalibrationSize {
                width: got.width,
                height: got.height,
                expected_width,
                expected_height,
            },
        ));
    }
    Ok(mat)
}

/// Reads and rectifies a EuRoC pair.
fn read_rectified(
    rectifier: &StereoRectifier,
    frame: &StereoFrame,
) -> std::result::Result<(GrayImage, GrayImage), Unreadable> {
    let left = read_raw(&frame.left, rectifier)?;
    let right = read_raw(&frame.right, rectifier)?;
    let pair = rectifier
        .rectify(&left, &right)
        .map_err(|e| Unreadable::new(&frame.left, UnreadableCause::Rectification(e.to_string())))?;
    let gray = |mat: &Mat, path: &Path| {
        GrayImage::from_mat(mat)
            .map_err(|e| Unreadable::new(path, UnreadableCause::Undecodable(e.to_string())))
    };
    Ok((
        gray(&pair.left, &frame.left)?,
        gray(&pair.right, &frame.right)?,
    ))
}
