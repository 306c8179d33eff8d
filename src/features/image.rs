use std::path::Path;

use opencv::core::Mat;
use opencv::prelude::*;

use super::FeatureError;

/// Largest accepted image side, in pixels.
pub const MAX_IMAGE_SIDE: usize = 16384;
/// Smallest accepted image side, in pixels (one 8-px descriptor cell plus margins).
pub const MIN_IMAGE_SIDE: usize = 16;

/// A borrowed 8-bit gray image with an arbitrary row stride.
#[derive(Clone, Copy, Debug)]
pub struct GrayImageView<'a> {
    data: &'a [u8],
    width: usize,
    height: usize,
    stride: usize,
}

impl<'a> GrayImageView<'a> {
    /// Wraps a buffer; checks sizes, the stride and the buffer length.
    pub fn new(
        data: &'a [u8],
        width: usize,
        height: usize,
        stride: usize,
    ) -> Result<Self, FeatureError> {
        if width == 0 || height == 0 {
            return Err(FeatureError::EmptyImage { width, height });
        }
        if width > MAX_IMAGE_SIDE || height > MAX_IMAGE_SIDE {
            return Err(FeatureError::ImageTooLarge {
                width,
                height,
                max_side: MAX_IMAGE_SIDE,
            });
        }
        if stride < width {
            return Err(FeatureError::StrideTooSmall { stride, width });
        }
        let required = stride * (height - 1) + width;
        if data.len() < required {
            return Err(FeatureError::BufferTooSmall {
                required,
                actual: data.len(),
                width,
                height,
                stride,
            });
        }
        Ok(Self {
            data,
            width,
            height,
            stride,
        })
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Bytes per row.
    pub fn stride(&self) -> usize {
        self.stride
    }

    /// Row `y` (exactly `width` bytes). Panics when `y >= height`.
    pub fn row(&self, y: usize) -> &'a [u8] {
        &self.data[y * self.stride..y * self.stride + self.width]
    }

    /// The pixel at column `x`, row `y`. Panics when out of range.
    pub fn get(&self, x: usize, y: usize) -> u8 {
        self.data[y * self.stride + x]
    }

    /// A contiguous owned copy.
    pub fn to_owned_image(&self) -> GrayImage {
        let mut data = Vec::with_capacity(self.width * self.height);
        for y in 0..self.height {
            data.extend_from_slice(self.row(y));
        }
        GrayImage {
            data,
            width: self.width,
            height: self.height,
        }
    }
}

/// An owned, contiguous 8-bit gray image.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GrayImage {
    data: Vec<u8>,
    width: usize,
    height: usize,
}

impl GrayImage {
    /// Takes a contiguous row-major buffer of `width * height` bytes.
    pub fn from_vec(data: Vec<u8>, width: usize, height: usize) -> Result<Self, FeatureError> {
        GrayImageView::new(&data, width, height, width)?;
        Ok(Self {
            data,
            width,
            height,
        })
    }

    /// Reads an image file (any format OpenCV decodes) and converts it to gray.
    pub fn load(path: &Path) -> Result<Self, FeatureError> {
        let read_err = |reason: String| FeatureError::ImageRead {
            path: path.to_path_buf(),
            reason,
        };
        if !path.is_file() {
            return Err(read_err("no such file".into()));
        }
        let name = path
            .to_str()
            .ok_or_else(|| read_err("path is not valid UTF-8".into()))?;
        let mat = opencv::imgcodecs::imread(name, opencv::imgcodecs::IMREAD_GRAYSCALE)
            .map_err(|e| read_err(e.to_string()))?;
        if mat.empty() {
            return Err(read_err(
                "OpenCV could not decode it (unknown format or corrupt file)".into(),
            ));
        }
        Self::from_mat(&mat)
    }

    /// Copies an 8-bit OpenCV matrix; 3- and 4-channel images are converted to gray.
    pub fn from_mat(mat: &Mat) -> Result<Self, FeatureError> {
        use opencv::core::{CV_8UC1, CV_8UC3, CV_8UC4};
        let gray = match mat.typ() {
            t if t == CV_8UC1 => mat.try_clone()?,
            t if t == CV_8UC3 || t == CV_8UC4 => {
                let code = if t == CV_8UC3 {
                    opencv::imgproc::COLOR_BGR2GRAY
                } else {
                    opencv::imgproc::COLOR_BGRA2GRAY
                };
                let mut g = Mat::default();
                opencv::imgproc::cvt_color_def(mat, &mut g, code)?;
                g
            }
            t => {
                return Err(FeatureError::UnsupportedImageType(
                    opencv::core::type_to_string(t)?,
                ))
            }
        };
        let width = gray.cols().max(0) as usize;
        let height = gray.rows().max(0) as usize;
        if width == 0 || height == 0 {
            return Err(FeatureError::EmptyImage { width, height });
        }
        let gray = if gray.is_continuous() {
            gray
        } else {
            gray.try_clone()?
        };
        let data = gray.data_bytes()?.to_vec();
        Self::from_vec(data, width, height)
    }

    /// Converts a contiguous row-major colour image of `channels` (3 or 4)
    /// interleaved bytes per pixel to gray with OpenCV's weights (as
    /// `cv2.cvtColor` does): `bgr` says whether the channels are in OpenCV's
    /// order (BGR/BGRA, as `cv2.imread` gives) or RGB/RGBA.
    pub fn from_interleaved(
        data: &[u8],
        width: usize,
        height: usize,
        channels: usize,
        bgr: bool,
    ) -> Result<Self, FeatureError> {
        use opencv::core::{CV_8UC3, CV_8UC4};
        let typ = match channels {
            3 => CV_8UC3,
            4 => CV_8UC4,
            other => {
                return Err(FeatureError::UnsupportedImageType(format!(
                    "{other} channels (give 1, 3 or 4)"
                )))
            }
        };
        if width == 0 || height == 0 {
            return Err(FeatureError::EmptyImage { width, height });
        }
        let needed = width * height * channels;
        if data.len() < needed {
            return Err(FeatureError::BufferTooSmall {
                required: needed,
                actual: data.len(),
                width,
                height,
                stride: width * channels,
            });
        }
        let code = match (channels, bgr) {
            (3, true) => opencv::imgproc::COLOR_BGR2GRAY,
            (3, false) => opencv::imgproc::COLOR_RGB2GRAY,
            (_, true) => opencv::imgproc::COLOR_BGRA2GRAY,
            (_, false) => opencv::imgproc::COLOR_RGBA2GRAY,
        };
        let flat = Mat::from_slice(&data[..needed])?;
        let colour = flat.reshape(channels as i32, height as i32)?;
        if colour.typ() != typ {
            return Err(FeatureError::UnsupportedImageType(format!(
                "{channels} channels reshaped to {}",
                opencv::core::type_to_string(colour.typ())?
            )));
        }
        let mut gray = Mat::default();
        opencv::imgproc::cvt_color_def(&colour, &mut gray, code)?;
        Self::from_mat(&gray)
    }

    /// Wraps the pixels in an OpenCV matrix (a copy).
    pub fn to_mat(&self) -> Result<Mat, FeatureError> {
        let flat = Mat::from_slice(&self.data)?;
        Ok(flat.reshape(1, self.height as i32)?.try_clone()?)
    }

    /// A borrowed view.
    pub fn view(&self) -> GrayImageView<'_> {
        GrayImageView {
            data: &self.data,
            width: self.width,
            height: self.height,
            stride: self.width,
        }
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// The row-major pixels.
    pub fn as_slice(&self) -> &[u8] {
        &self.data
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use opencv::core::{Scalar, CV_16UC1, CV_32FC1, CV_8UC3};

    #[test]
    fn colour_is_converted_and_other_types_are_refused() {
        let colour =
            Mat::new_rows_cols_with_default(20, 30, CV_8UC3, Scalar::new(10.0, 20.0, 30.0, 0.0))
                .unwrap();
        let gray = GrayImage::from_mat(&colour).unwrap();
        assert_eq!((gray.width(), gray.height()), (30, 20));
        // OpenCV's BGR→gray weights: 0.114 B + 0.587 G + 0.299 R.
        assert_eq!(gray.as_slice()[0], 22);
        for typ in [CV_32FC1, CV_16UC1] {
            let m = Mat::new_rows_cols_with_default(20, 30, typ, Scalar::all(0.0)).unwrap();
            assert!(matches!(
                GrayImage::from_mat(&m),
                Err(FeatureError::UnsupportedImageType(_))
            ));
        }
        assert!(matches!(
            GrayImage::from_mat(&Mat::default()),
            Err(FeatureError::UnsupportedImageType(_) | FeatureError::EmptyImage { .. })
        ));
    }

    #[test]
    fn mat_round_trip_keeps_the_pixels() {
        let pixels: Vec<u8> = (0..12 * 7).map(|i| (i * 3 % 256) as u8).collect();
        let image = GrayImage::from_vec(pixels.clone(), 12, 7).unwrap();
        let back = GrayImage::from_mat(&image.to_mat().unwrap()).unwrap();
        assert_eq!(back.as_slice(), &pixels[..]);
    }
}
