//! The images `spslam loops` searches: a folder in name order, or a
//! sequence with ground truth (`--dataset`), whose depth for the judgement
//! comes from the synthetic scene, its depth images, its stereo pairs or a
//! nominal distance.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use spslam::camera::{DepthImage, Sensor};
use spslam::eval::place_recognition::OverlapCamera;
use spslam::features::GrayImage;
use spslam::matching::dense::sgbm_disparity;
use spslam::settings::SlamSettings;

use super::truth::{self, FrameTruth};
use super::LoopsArgs;
use crate::run::source::{InputFrame, Source, DEFAULT_DEPTH_MAP_FACTOR};
use crate::vocab::images::list_images;

/// Where the images come from.
pub enum Input {
    /// A folder, in name order.
    Folder(Vec<PathBuf>),
    /// A sequence with ground truth.
    Dataset(Box<DatasetInput>),
}

/// A sequence's frames, how to read them, and its ground truth.
pub struct DatasetInput {
    /// The dataset as given.
    pub spec: String,
    source: Source,
    frames: Vec<InputFrame>,
    depth_factor: f64,
    /// The ground truth gathered as frames are read.
    pub truth: FrameTruth,
    /// Depth from the stereo pairs (sequences with right images and no
    /// depth images).
    stereo_depth: Option<StereoDepth>,
}

/// How depth is computed from a rectified stereo pair for the ground truth.
#[derive(Debug, Clone, Copy)]
struct StereoDepth {
    fx: f64,
    baseline: f64,
}

/// Disparities searched by the dense matcher: 128 px is 3 m on KITTI.
const TRUTH_MAX_DISPARITY: usize = 128;

impl StereoDepth {
    /// Depth (m) of every pixel of the pair from OpenCV's semi-global
    /// matching; 0 where it finds no disparity.
    fn depth(&self, left: &GrayImage, right: &GrayImage) -> Result<DepthImage> {
        let disparity = sgbm_disparity(left.view(), right.view(), TRUTH_MAX_DISPARITY)?;
        let (w, h) = (left.width(), left.height());
        let mut metres = vec![0f32; w * h];
        for y in 0..h {
            for x in 0..w {
                if let Some(d) = disparity.at(x as f32, y as f32).filter(|d| *d > 0.0) {
                    metres[y * w + x] = (self.fx * self.baseline / f64::from(d)) as f32;
                }
            }
        }
        Ok(DepthImage::from_metres(metres, w, h)?)
    }
}

impl Input {
    /// Opens the images of `args` (`--images` or `--dataset`).
    pub fn open(args: &LoopsArgs) -> Result<Self> {
        let Some(spec) = &args.dataset else {
            let folder = args.images.clone().unwrap_or_default();
            return Ok(Self::Folder(list_images(std::slice::from_ref(&folder))?));
        };
        let source = Source::open(spec)?;
        // `spslam synth` writes synthetic.json beside image_0/.
        let first_image = source
            .frames(Sensor::Monocular)?
            .first()
            .map(|f| f.image.clone());
        let folder = first_image
            .as_deref()
            .and_then(Path::parent)
            .and_then(Path::parent)
            .map(Path::to_path_buf)
            .unwrap_or_default();
        let scene = truth::synthetic_scene(&folder)?;
        let settings = match &args.settings {
            Some(path) => SlamSettings::from_file(path)?,
            None => source.default_settings()?,
        };
        // Depth where the sequence has it and the scene cannot be cast
        // into: RGB-D depth images, else stereo pairs (matched densely),
        // else the images alone.
        let stereo = settings
            .camera
            .baseline
            .filter(|_| scene.is_none() && args.truth_depth.is_none());
        let frames = match (&scene, source.frames(Sensor::Rgbd)) {
            (None, Ok(frames)) => frames,
            _ => match stereo.and_then(|_| source.frames(Sensor::Stereo).ok()) {
                Some(frames) => frames,
                None => source.frames(Sensor::Monocular)?,
            },
        };
        let depth_factor = settings
            .depth_map_factor
            .unwrap_or(DEFAULT_DEPTH_MAP_FACTOR);
        let (width, height) = source.first_size(&frames, depth_factor)?;
        let c = &settings.camera;
        let camera = OverlapCamera {
            fx: c.fx,
            fy: c.fy,
            cx: c.cx,
            cy: c.cy,
            width,
            height,
        };
        let truth = FrameTruth::new(&source, &frames, camera, args.truth_depth, scene)?;
        let stereo_depth = stereo.map(|baseline| StereoDepth {
            fx: settings.camera.fx,
            baseline,
        });
        Ok(Self::Dataset(Box::new(DatasetInput {
            spec: spec.clone(),
            source,
            frames,
            depth_factor,
            truth,
            stereo_depth,
        })))
    }

    /// The images' file names, in reading order.
    pub fn names(&self) -> Vec<String> {
        let name = |p: &Path| {
            p.file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default()
        };
        match self {
            Self::Folder(paths) => paths.iter().map(|p| name(p)).collect(),
            Self::Dataset(d) => d.frames.iter().map(|f| name(&f.image)).collect(),
        }
    }

    /// Reads image `i` (and records its depth in the ground truth).
    pub fn read(&mut self, i: usize) -> Result<GrayImage> {
        match self {
            Self::Folder(paths) => {
                let path = &paths[i];
                GrayImage::load(path)
                    .with_context(|| format!("cannot read image {}", path.display()))
            }
            Self::Dataset(d) => {
                let images = d.source.load(&d.frames[i], None, d.depth_factor)?;
                match (&images.right, d.stereo_depth) {
                    (Some(right), Some(stereo)) => {
                        let depth = stereo.depth(&images.image, right)?;
                        d.truth.add_frame(Some(&depth));
                    }
                    _ => d.truth.add_frame(images.depth.as_ref()),
                }
                Ok(images.image)
            }
        }
    }
}
