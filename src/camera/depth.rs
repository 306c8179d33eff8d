//! Registered depth images (RGB-D): metres per pixel, read from the 16-bit
//! PNGs of TUM RGB-D and `spslam synth` with ORB-SLAM3's `DepthMapFactor`.

use std::path::{Path, PathBuf};

use opencv::core::{Mat, MatTraitConst, MatTraitConstManual, CV_16U, CV_32F};
use opencv::imgcodecs;

/// Median depths outside this range (metres) mean the depth scale is wrong:
/// no RGB-D sensor measures 100 m, and a median under 1 cm is a scale error.
const PLAUSIBLE_MEDIAN_M: (f32, f32) = (0.01, 100.0);

/// Why a depth image cannot be used. Each names the file when it came from one.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DepthError {
    /// The file is missing or does not decode.
    #[error("depth image {}: cannot be read: {reason}", .path.display())]
    Unreadable {
        /// The file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// The pixels are not 16-bit unsigned or 32-bit float depths.
    #[error(
        "depth image {}: pixels are {found}; a depth image is single-channel 16-bit (e.g. TUM's PNGs) or 32-bit float",
        .path.display()
    )]
    WrongType {
        /// The file.
        path: PathBuf,
        /// What it holds, e.g. `8-bit, 3 channels`.
        found: String,
    },
    /// The depth image's size differs from its colour image's.
    #[error(
        "depth image {}: {width}x{height}, but the colour image is {expected_width}x{expected_height}; depth must be registered to the colour camera",
        .path.display()
    )]
    WrongSize {
        /// The file.
        path: PathBuf,
        /// Its width.
        width: usize,
        /// Its height.
        height: usize,
        /// The colour image's width.
        expected_width: usize,
        /// The colour image's height.
        expected_height: usize,
    },
    /// The depths read with the factor are implausible (the factor is wrong).
    #[error(
        "depth image {}: the median depth is {median_m} m with DepthMapFactor {factor}; check RGBD.DepthMapFactor (TUM RGB-D: 5000, millimetre images: 1000)",
        .path.display()
    )]
    WrongScale {
        /// The file.
        path: PathBuf,
        /// The median of the valid depths, metres.
        median_m: f32,
        /// The factor used.
        factor: f64,
    },
    /// The factor itself is not a positive number.
    #[error("DepthMapFactor {0} must be a positive number")]
    InvalidFactor(f64),
    /// An in-memory buffer whose length is not `width · height`.
    #[error("depth buffer of {len} values for a {width}x{height} image")]
    BufferLength {
        /// Values given.
        len: usize,
        /// Width.
        width: usize,
        /// Height.
        height: usize,
    },
}

/// A depth image in metres, row-major; 0 (or any value ≤ 0 or not finite)
/// is "no depth".
#[derive(Debug, Clone, PartialEq)]
pub struct DepthImage {
    metres: Vec<f32>,
    width: usize,
    height: usize,
}

impl DepthImage {
    /// A depth image from metres, row-major.
    pub fn from_metres(metres: Vec<f32>, width: usize, height: usize) -> Result<Self, DepthError> {
        if metres.len() != width * height || width == 0 || height == 0 {
            return Err(DepthError::BufferLength {
                len: metres.len(),
                width,
                height,
            });
        }
        Ok(Self {
            metres,
            width,
            height,
        })
    }

    /// A depth image from raw values held in memory (16-bit or float, as a
    /// depth PNG or EXR holds them), divided by `factor` exactly as
    /// [`Self::load`] divides a file's.
    pub fn from_raw<T: Copy + Into<f32>>(
        values: &[T],
        width: usize,
        height: usize,
        factor: f64,
    ) -> Result<Self, DepthError> {
        if !(factor.is_finite() && factor > 0.0) {
            return Err(DepthError::InvalidFactor(factor));
        }
        let scale = (1.0 / factor) as f32;
        let metres = values.iter().map(|&v| v.into() * scale).collect();
        Self::from_metres(metres, width, height)
    }

    /// Reads a depth image: 16-bit values divided by `factor` (ORB-SLAM3's
    /// `DepthMapFactor`: `mImDepth.convertTo(CV_32F, 1/factor)`), or 32-bit
    /// float values divided by it. The median valid depth must be
    /// plausible (1 cm to 100 m), which catches a wrong factor.
    pub fn load(path: &Path, factor: f64) -> Result<Self, DepthError> {
        if !(factor.is_finite() && factor > 0.0) {
            return Err(DepthError::InvalidFactor(factor));
        }
        let unreadable = |reason: String| DepthError::Unreadable {
            path: path.to_path_buf(),
            reason,
        };
        if !path.is_file() {
            return Err(unreadable("no such file".into()));
        }
        let text = path
            .to_str()
            .ok_or_else(|| unreadable("the path is not valid UTF-8".into()))?;
        let mat = imgcodecs::imread(text, imgcodecs::IMREAD_UNCHANGED)
            .map_err(|e| unreadable(e.to_string()))?;
        if mat.empty() {
            return Err(unreadable(
                "OpenCV could not decode it (unknown format or corrupt file)".into(),
            ));
        }
        let image = Self::from_mat(&mat, factor).map_err(|e| match e {
            MatError::Type(found) => DepthError::WrongType {
                path: path.to_path_buf(),
                found,
            },
            MatError::OpenCv(reason) => unreadable(reason),
        })?;
        // The scale check reads every 7th pixel: a median needs no more,
        // and this runs on every frame.
        if let Some(median_m) = median_of(image.metres.iter().step_by(7).copied()) {
            if !(PLAUSIBLE_MEDIAN_M.0..=PLAUSIBLE_MEDIAN_M.1).contains(&median_m) {
                return Err(DepthError::WrongScale {
                    path: path.to_path_buf(),
                    median_m,
                    factor,
                });
            }
        }
        Ok(image)
    }

    fn from_mat(mat: &Mat, factor: f64) -> Result<Self, MatError> {
        let (depth, channels) = (mat.depth(), mat.channels());
        let opencv = |e: opencv::Error| MatError::OpenCv(e.to_string());
        let (width, height) = (mat.cols() as usize, mat.rows() as usize);
        let scale = (1.0 / factor) as f32;
        let metres: Vec<f32> = match (depth, channels) {
            (CV_16U, 1) => {
                let mut out = Vec::with_capacity(width * height);
                for y in 0..mat.rows() {
                    let row = mat.at_row::<u16>(y).map_err(opencv)?;
                    out.extend(row.iter().map(|&v| f32::from(v) * scale));
                }
                out
            }
            (CV_32F, 1) => {
                let mut out = Vec::with_capacity(width * height);
                for y in 0..mat.rows() {
                    let row = mat.at_row::<f32>(y).map_err(opencv)?;
                    out.extend(row.iter().map(|&v| v * scale));
                }
                out
            }
            _ => {
                let bits = match depth {
                    opencv::core::CV_8U | opencv::core::CV_8S => "8-bit",
                    CV_16U | opencv::core::CV_16S => "16-bit",
                    CV_32F | opencv::core::CV_32S => "32-bit",
                    _ => "64-bit",
                };
                return Err(MatError::Type(format!("{bits}, {channels} channels")));
            }
        };
        Self::from_metres(metres, width, height)
            .map_err(|e| MatError::OpenCv(format!("unexpected layout: {e}")))
    }

    /// Width, pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height, pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// The depth at the pixel holding `(x, y)` (ORB-SLAM3's
    /// `ComputeStereoFromRGBD` reads `imDepth.at<float>(v, u)` at the
    /// keypoint's rounded-down position), when valid.
    pub fn depth_at(&self, x: f32, y: f32) -> Option<f32> {
        if !(x >= 0.0 && y >= 0.0) {
            return None;
        }
        let (u, v) = (x as usize, y as usize);
        if u >= self.width || v >= self.height {
            return None;
        }
        self.metres
            .get(v * self.width + u)
            .copied()
            .filter(|d| d.is_finite() && *d > 0.0)
    }

    /// The depths, metres, row-major.
    pub fn as_slice(&self) -> &[f32] {
        &self.metres
    }

    /// The median of the valid depths; `None` when no pixel has one.
    pub fn median_valid(&self) -> Option<f32> {
        median_of(self.metres.iter().copied())
    }

    /// Checks the size against the colour image's, naming `path` when not.
    pub fn check_size(
        &self,
        path: &Path,
        expected_width: usize,
        expected_height: usize,
    ) -> Result<(), DepthError> {
        if (self.width, self.height) == (expected_width, expected_height) {
            return Ok(());
        }
        Err(DepthError::WrongSize {
            path: path.to_path_buf(),
            width: self.width,
            height: self.height,
            expected_width,
            expected_height,
        })
    }
}

/// The median of the valid (finite, positive) depths among `depths`.
fn median_of(depths: impl Iterator<Item = f32>) -> Option<f32> {
    let mut valid: Vec<f32> = depths.filter(|d| d.is_finite() && *d > 0.0).collect();
    crate::stats::upper_median(&mut valid)
}

/// Why a matrix is not a depth image (before the path is attached).
enum MatError {
    Type(String),
    OpenCv(String),
}

#[cfg(test)]
mod tests {
    use super::*;
    use opencv::core::{Scalar, Vector, CV_8UC1, CV_8UC3};

    fn temp_png(name: &str, mat: &Mat) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("spslam-depth-{}", std::process::id()));
        let _ = std::fs::create_dir_all(&dir);
        let path = dir.join(name);
        let written = path
            .to_str()
            .is_some_and(|p| imgcodecs::imwrite(p, mat, &Vector::new()).unwrap_or(false));
        assert!(written, "could not write {}", path.display());
        path
    }

    fn filled(rows: i32, cols: i32, typ: i32, value: f64) -> Mat {
        Mat::new_rows_cols_with_default(rows, cols, typ, Scalar::all(value))
            .unwrap_or_else(|e| panic!("{e}"))
    }

    #[test]
    fn sixteen_bit_png_reads_in_metres() {
        let path = temp_png("ok.png", &filled(4, 6, CV_16U, 10_000.0));
        let depth = DepthImage::load(&path, 5000.0).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!((depth.width(), depth.height()), (6, 4));
        assert_eq!(depth.depth_at(2.7, 3.9), Some(2.0));
        assert_eq!(depth.depth_at(6.0, 0.0), None);
        assert_eq!(depth.depth_at(f32::NAN, 0.0), None);
        assert!(depth.check_size(&path, 6, 4).is_ok());
        let err = depth.check_size(&path, 640, 480).unwrap_err();
        assert!(matches!(err, DepthError::WrongSize { width: 6, .. }));
        assert!(err.to_string().contains("ok.png"), "{err}");
    }

    #[test]
    fn wrong_type_scale_and_file_are_named() {
        let gray = temp_png("gray.png", &filled(4, 6, CV_8UC1, 10.0));
        let err = DepthImage::load(&gray, 5000.0).unwrap_err();
        assert!(matches!(err, DepthError::WrongType { .. }), "{err}");
        assert!(err.to_string().contains("gray.png") && err.to_string().contains("8-bit"));
        let colour = temp_png("colour.png", &filled(4, 6, CV_8UC3, 10.0));
        assert!(matches!(
            DepthImage::load(&colour, 5000.0),
            Err(DepthError::WrongType { .. })
        ));
        let tum = temp_png("tum.png", &filled(4, 6, CV_16U, 10_000.0));
        let err = DepthImage::load(&tum, 1.0).unwrap_err();
        assert!(
            matches!(err, DepthError::WrongScale { median_m, .. } if median_m == 10_000.0),
            "{err}"
        );
        assert!(err.to_string().contains("tum.png"));
        assert!(matches!(
            DepthImage::load(&tum, 0.0),
            Err(DepthError::InvalidFactor(_))
        ));
        let missing = DepthImage::load(Path::new("/no/such/depth.png"), 5000.0).unwrap_err();
        assert!(missing.to_string().contains("/no/such/depth.png"));
        let zeros = temp_png("zeros.png", &filled(4, 6, CV_16U, 0.0));
        let empty = DepthImage::load(&zeros, 5000.0).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(empty.median_valid(), None);
    }

    #[test]
    fn buffer_length_is_checked() {
        assert!(DepthImage::from_metres(vec![1.0; 5], 2, 3).is_err());
        assert!(DepthImage::from_metres(vec![1.0; 6], 2, 3).is_ok());
    }
}
