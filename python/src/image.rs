//! NumPy images in: a `uint8` array of shape (H, W), (H, W, 1), (H, W, 3) or
//! (H, W, 4), converted to the gray image spslam works on.

use numpy::{PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use spslam::features::GrayImage;

use crate::errors::feature_error;

/// Copies `image` (named `what` in errors) into a gray image: colour
/// channels are BGR(A) as `cv2.imread` gives them, or RGB(A) when `rgb`.
pub fn gray_from_numpy(image: &Bound<'_, PyAny>, what: &str, rgb: bool) -> PyResult<GrayImage> {
    let array: PyReadonlyArrayDyn<'_, u8> = match image.extract() {
        Ok(array) => array,
        Err(_) => {
            let kind = match image.getattr("dtype") {
                Ok(dtype) => format!("a NumPy array of dtype {}", dtype.str()?),
                Err(_) => format!("{}", image.get_type().name()?),
            };
            return Err(PyTypeError::new_err(format!(
                "{what} must be a NumPy uint8 array (gray H×W or colour H×W×3/4), got {kind}"
            )));
        }
    };
    let shape = array.shape().to_vec();
    let (height, width, channels) = match shape.as_slice() {
        [h, w] => (*h, *w, 1),
        [h, w, c] if matches!(c, 1 | 3 | 4) => (*h, *w, *c),
        _ => {
            return Err(PyValueError::new_err(format!(
                "{what} has shape {shape:?}; give H×W (gray), H×W×3 or H×W×4 (colour)"
            )))
        }
    };
    let pixels: Vec<u8> = match array.as_slice() {
        Ok(contiguous) => contiguous.to_vec(),
        Err(_) => array.as_array().iter().copied().collect(),
    };
    let gray = if channels == 1 {
        GrayImage::from_vec(pixels, width, height)
    } else {
        GrayImage::from_interleaved(&pixels, width, height, channels, !rgb)
    };
    gray.map_err(feature_error)
}
