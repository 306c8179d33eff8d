//! The input sequence of `spslam run` and how its frames are read. A frame
//! that cannot be used comes back as an [`Unreadable`]: the image at fault
//! and the cause, so that the run can skip it and say why.

use std::path::{Path, PathBuf};

use anyhow::{bail, Result};
use opencv::core::{Mat, MatTraitConst};
use opencv::imgcodecs;
use spslam::camera::{DepthError, DepthImage, Sensor};
use spslam::dataset::{StereoFrame, StereoRectifier};
use spslam::eval::{read_euroc, read_kitti, read_tum, Trajectory};
use spslam::features::{FeatureError, GrayImage};
use spslam::settings::SlamSettings;
use spslam::tracking::SensorImages;

use super::euroc_layout::EurocLayout;
use super::kitti_layout::KittiLayout;
use super::tum_layout::TumLayout;

/// Depth units per metre when the settings give no `DepthMapFactor`: the
/// TUM RGB-D format's (and `spslam synth`'s) 5000.
pub const DEFAULT_DEPTH_MAP_FACTOR: f64 = 5000.0;

/// One input frame: its image and, by sensor, the right or depth image.
#[derive(Debug, Clone, PartialEq)]
pub struct InputFrame {
    /// Time, seconds.
    pub timestamp: f64,
    /// The (left) image.
    pub image: PathBuf,
    /// The right image (stereo).
    pub right: Option<PathBuf>,
    /// The depth image (RGB-D).
    pub depth: Option<PathBuf>,
}

/// A frame's images, read.
pub struct LoadedImages {
    /// The (left) image, gray.
    pub image: GrayImage,
    /// The right image (stereo).
    pub right: Option<GrayImage>,
    /// The depth image, metres (RGB-D).
    pub depth: Option<DepthImage>,
}

impl LoadedImages {
    /// The images as the system takes them.
    pub fn views(&self) -> SensorImages<'_> {
        match (&self.right, &self.depth) {
            (Some(right), _) => SensorImages::Stereo {
                left: self.image.view(),
                right: right.view(),
            },
            (None, Some(depth)) => SensorImages::Rgbd {
                image: self.image.view(),
                depth,
            },
            (None, None) => SensorImages::Monocular(self.image.view()),
        }
    }
}

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
    /// The depth image cannot be used (wrong size, type or scale).
    #[error("{0}")]
    Depth(DepthError),
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

/// A sequence and how to read its images.
pub enum Source {
    /// KITTI or a synthetic sequence in KITTI's layout.
    Kitti(Box<KittiLayout>),
    /// An EuRoC ASL folder, rectified on reading.
    Euroc(EurocLayout),
    /// A TUM RGB-D folder (or `spslam synth` output read as one).
    Tum(Box<TumLayout>),
}

impl Source {
    /// Opens `kitti:DIR`, `euroc:DIR`, `synth:DIR` or `tum:DIR`.
    pub fn open(spec: &str) -> Result<Self> {
        let Some((kind, dir)) = spec.split_once(':') else {
            bail!("--dataset `{spec}` is not KIND:DIR (kitti:, euroc:, synth: or tum:)");
        };
        let dir = PathBuf::from(dir);
        match kind {
            "kitti" | "synth" => Ok(Self::Kitti(Box::new(KittiLayout::open(&dir)?))),
            "euroc" => Ok(Self::Euroc(EurocLayout::open(&dir)?)),
            "tum" => Ok(Self::Tum(Box::new(TumLayout::open(&dir)?))),
            other => bail!("unknown dataset kind `{other}` (kitti, euroc, synth or tum)"),
        }
    }

    /// The sensor a run uses when `--sensor` is not given: RGB-D for TUM
    /// folders (they have no right image), monocular for a KITTI-layout
    /// sequence without `image_1/`, stereo otherwise.
    pub fn default_sensor(&self) -> Sensor {
        match self {
            Self::Tum(_) => Sensor::Rgbd,
            Self::Kitti(seq) if seq.left_only => Sensor::Monocular,
            _ => Sensor::Stereo,
        }
    }

    /// Every frame of the sequence, with the images `sensor` needs; an
    /// error when the sequence does not hold them.
    pub fn frames(&self, sensor: Sensor) -> Result<Vec<InputFrame>> {
        let stereo = |frames: &[StereoFrame], depth: bool| -> Vec<InputFrame> {
            frames
                .iter()
                .map(|f| InputFrame {
                    timestamp: f.timestamp,
                    image: f.left.clone(),
                    right: (sensor == Sensor::Stereo).then(|| f.right.clone()),
                    depth: depth.then(|| depth_beside(&f.left)).flatten(),
                })
                .collect()
        };
        match (self, sensor) {
            (Self::Kitti(seq), Sensor::Rgbd) => {
                let depth_dir = seq
                    .frames
                    .first()
                    .and_then(|f| depth_beside(&f.left))
                    .and_then(|d| d.parent().map(Path::to_path_buf));
                if !depth_dir.is_some_and(|d| d.is_dir()) {
                    bail!("--sensor rgbd needs depth images: this KITTI-layout sequence has no depth/ folder beside image_0/ (`spslam synth` writes one)");
                }
                Ok(stereo(&seq.frames, true))
            }
            (Self::Kitti(seq), Sensor::Stereo) if seq.left_only => {
                bail!("--sensor stereo needs right images: this KITTI-layout sequence has no image_1/ folder (use --sensor mono)")
            }
            (Self::Kitti(seq), _) => Ok(stereo(&seq.frames, false)),
            (Self::Euroc(_), Sensor::Rgbd) => {
                bail!("--sensor rgbd needs depth images; EuRoC has none (use mono or stereo)")
            }
            (Self::Euroc(seq), _) => Ok(stereo(&seq.frames, false)),
            (Self::Tum(_), Sensor::Stereo) => {
                bail!("--sensor stereo needs right images; a TUM RGB-D folder has none (use rgbd or mono)")
            }
            (Self::Tum(seq), _) => Ok(seq
                .frames
                .iter()
                .map(|f| InputFrame {
                    timestamp: f.timestamp,
                    image: f.rgb.clone(),
                    right: None,
                    depth: (sensor == Sensor::Rgbd).then(|| f.depth.clone()),
                })
                .collect()),
        }
    }

    /// Whether the sequence is in KITTI's layout (KITTI or synthetic).
    pub fn is_kitti(&self) -> bool {
        matches!(self, Self::Kitti(_))
    }

    /// Settings from the calibration: KITTI's P0/P1, EuRoC's rectified
    /// camera, a TUM folder's `calib.txt` (from `spslam synth`). Every
    /// stereo depth is kept (no `Tracking.maxDepth`): points beyond
    /// `ThDepth` are ORB-SLAM3's "far" points, tracked and optimised like
    /// the others.
    pub fn default_settings(&self) -> Result<SlamSettings> {
        match self {
            Self::Kitti(seq) => {
                let c = &seq.calibration;
                Ok(SlamSettings::rectified_stereo(c.fx, c.fy, c.cx, c.cy, c.baseline))
            }
            Self::Euroc(seq) => {
                let r = &seq.rectifier;
                let mut s =
                    SlamSettings::rectified_stereo(r.fx(), r.fy(), r.cx(), r.cy(), r.baseline());
                s.camera.fps = 20.0;
                Ok(s)
            }
            Self::Tum(seq) => match &seq.calibration {
                Some(c) => {
                    let mut s = SlamSettings::rectified_stereo(c.fx, c.fy, c.cx, c.cy, c.baseline);
                    s.depth_map_factor = Some(DEFAULT_DEPTH_MAP_FACTOR);
                    Ok(s)
                }
                None => bail!(
                    "a TUM RGB-D folder carries no camera calibration: pass --settings with ORB-SLAM3's settings for it (e.g. TUM1.yaml: Camera.fx…, Camera.bf, DepthMapFactor: 5000.0)"
                ),
            },
        }
    }

    /// The image size of the first frame of `frames` that can be read, to
    /// size the camera rig. An error when none can.
    pub fn first_size(&self, frames: &[InputFrame], depth_factor: f64) -> Result<(usize, usize)> {
        let mut first_error = None;
        for (index, frame) in frames.iter().enumerate() {
            match self.load(frame, None, depth_factor) {
                Ok(images) => return Ok((images.image.width(), images.image.height())),
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

    /// Reads (and for EuRoC rectifies) a frame's images. With `expected`,
    /// the image must have that size (the first frame's); the right and
    /// depth images must have the image's.
    pub fn load(
        &self,
        frame: &InputFrame,
        expected: Option<(usize, usize)>,
        depth_factor: f64,
    ) -> std::result::Result<LoadedImages, Unreadable> {
        let (image, right) = match (self, &frame.right) {
            (Self::Euroc(seq), Some(right)) => {
                let (l, r) = read_rectified(&seq.rectifier, &frame.image, right)?;
                (l, Some(r))
            }
            (Self::Euroc(seq), None) => (read_rectified_left(&seq.rectifier, &frame.image)?, None),
            (_, Some(right)) => (read_gray(&frame.image)?, Some(read_gray(right)?)),
            (_, None) => (read_gray(&frame.image)?, None),
        };
        let size = |image: &GrayImage| (image.width(), image.height());
        if let Some((expected_width, expected_height)) = expected {
            let (width, height) = size(&image);
            if (width, height) != (expected_width, expected_height) {
                return Err(Unreadable::new(
                    &frame.image,
                    UnreadableCause::SizeChanged {
                        width,
                        height,
                        expected_width,
                        expected_height,
                    },
                ));
            }
        }
        if let (Some(right), Some(path)) = (&right, &frame.right) {
            if size(&image) != size(right) {
                return Err(Unreadable::new(
                    path,
                    UnreadableCause::StereoSizeMismatch {
                        left_width: image.width(),
                        left_height: image.height(),
                        right_width: right.width(),
                        right_height: right.height(),
                    },
                ));
            }
        }
        let depth = match &frame.depth {
            Some(path) => {
                let depth_error = |e: DepthError| Unreadable::new(path, UnreadableCause::Depth(e));
                let depth = DepthImage::load(path, depth_factor).map_err(depth_error)?;
                depth
                    .check_size(path, image.width(), image.height())
                    .map_err(depth_error)?;
                Some(depth)
            }
            None => None,
        };
        Ok(LoadedImages {
            image,
            right,
            depth,
        })
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
            Self::Tum(seq) => match &seq.ground_truth {
                Some(path) => Ok(Some(read_tum(path)?)),
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
    left_path: &Path,
    right_path: &Path,
) -> std::result::Result<(GrayImage, GrayImage), Unreadable> {
    let left = read_raw(left_path, rectifier)?;
    let right = read_raw(right_path, rectifier)?;
    let pair = rectifier
        .rectify(&left, &right)
        .map_err(|e| Unreadable::new(left_path, UnreadableCause::Rectification(e.to_string())))?;
    Ok((gray(&pair.left, left_path)?, gray(&pair.right, right_path)?))
}

/// Reads and rectifies a EuRoC left image alone (monocular).
fn read_rectified_left(
    rectifier: &StereoRectifier,
    path: &Path,
) -> std::result::Result<GrayImage, Unreadable> {
    let raw = read_raw(path, rectifier)?;
    let left = rectifier
        .rectify_left(&raw)
        .map_err(|e| Unreadable::new(path, UnreadableCause::Rectification(e.to_string())))?;
    gray(&left, path)
}

fn gray(mat: &Mat, path: &Path) -> std::result::Result<GrayImage, Unreadable> {
    GrayImage::from_mat(mat)
        .map_err(|e| Unreadable::new(path, UnreadableCause::Undecodable(e.to_string())))
}

/// `…/image_0/NAME` → `…/depth/NAME` (`spslam synth`'s depth maps).
fn depth_beside(image: &Path) -> Option<PathBuf> {
    let name = image.file_name()?;
    Some(image.parent()?.parent()?.join("depth").join(name))
}
