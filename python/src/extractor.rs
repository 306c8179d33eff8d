//! `spslam.Extractor` and the `spslam.Features` it returns.

use std::path::PathBuf;
use std::sync::Mutex;

use numpy::ndarray::{Array1, Array2};
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use spslam::features::sign_bits::pack_sign_bits;
use spslam::features::{AnmsMethod, Device, ExtractorConfig, Precision, SuperPointExtractor};

use crate::errors::{feature_error, SpslamError};
use crate::image::gray_from_numpy;

/// SuperPoint keypoints and 256-float descriptors, spread by ANMS
/// (the extractor of `spslam extract` and of the C ABI).
#[pyclass(module = "spslam", name = "Extractor")]
pub struct Extractor {
    inner: Mutex<SuperPointExtractor>,
    summary: String,
}

fn parse<T: std::str::FromStr<Err = spslam::features::FeatureError>>(value: &str) -> PyResult<T> {
    value.parse::<T>().map_err(feature_error)
}

#[pymethods]
impl Extractor {
    /// Loads the model (the first extractor of a process also loads ONNX
    /// Runtime's library, found through the `onnxruntime` package).
    #[new]
    #[pyo3(signature = (
        features = 1000,
        *,
        anms = "kdtree",
        levels = 1,
        scale_factor = 1.2,
        threshold = 0.005,
        nms_radius = 4,
        precision = "int8",
        device = "cpu",
        model = None,
        threads = 0,
        periodic_filter = true,
        exposure_stretch = true,
    ))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        features: usize,
        anms: &str,
        levels: usize,
        scale_factor: f32,
        threshold: f32,
        nms_radius: usize,
        precision: &str,
        device: &str,
        model: Option<PathBuf>,
        threads: usize,
        periodic_filter: bool,
        exposure_stretch: bool,
    ) -> PyResult<Self> {
        let defaults = ExtractorConfig::default();
        let mut config = ExtractorConfig {
            n_features: features,
            scale_factor,
            n_levels: levels,
            threshold,
            min_threshold: defaults.min_threshold.min(threshold),
            nms_radius,
            anms: parse::<AnmsMethod>(anms)?,
            precision: parse::<Precision>(precision)?,
            device: parse::<Device>(device)?,
            model_path: model,
            threads,
            ..defaults
        };
        config.periodic_filter.enabled = periodic_filter;
        if !exposure_stretch {
            config.exposure.target_range = 0.0;
        }
        let summary = format!(
            "Extractor(features={features}, anms={anms:?}, levels={levels}, precision={precision:?}, device={device:?}, model={:?})",
            config.resolved_model_path().display().to_string()
        );
        let extractor = py
            .detach(|| SuperPointExtractor::new(config))
            .map_err(feature_error)?;
        Ok(Self {
            inner: Mutex::new(extractor),
            summary,
        })
    }

    /// Detects keypoints and computes their descriptors. `image`: a NumPy
    /// `uint8` array, gray (H×W) or colour (H×W×3 or ×4, BGR as
    /// `cv2.imread` gives; `rgb=True` for RGB). The GIL is released while
    /// the network runs.
    #[pyo3(signature = (image, *, rgb = false))]
    fn extract(&self, py: Python<'_>, image: &Bound<'_, PyAny>, rgb: bool) -> PyResult<Features> {
        let gray = gray_from_numpy(image, "image", rgb)?;
        let features = py.detach(|| {
            let mut extractor = self
                .inner
                .lock()
                .map_err(|_| SpslamError::new_err("the extractor failed in another thread"))?;
            extractor.extract(gray.view()).map_err(feature_error)
        })?;
        Features::from_rust(py, features)
    }

    /// Floats per descriptor (256).
    #[getter]
    fn descriptor_len(&self) -> PyResult<usize> {
        Ok(self.locked()?.descriptor_len())
    }

    /// The model file loaded.
    #[getter]
    fn model_path(&self) -> PyResult<PathBuf> {
        Ok(self.locked()?.config().resolved_model_path())
    }

    fn __repr__(&self) -> String {
        self.summary.clone()
    }
}

impl Extractor {
    fn locked(&self) -> PyResult<std::sync::MutexGuard<'_, SuperPointExtractor>> {
        self.inner
            .lock()
            .map_err(|_| SpslamError::new_err("the extractor failed in another thread"))
    }
}

/// The features of one image, as NumPy arrays (row i of each is keypoint i).
#[pyclass(module = "spslam", name = "Features", frozen)]
pub struct Features {
    keypoints: Py<PyArray2<f32>>,
    scores: Py<PyArray1<f32>>,
    octaves: Py<PyArray1<i32>>,
    angles: Py<PyArray1<f32>>,
    sizes: Py<PyArray1<f32>>,
    descriptors: Py<PyArray2<f32>>,
    binary_descriptors: Py<PyArray2<u8>>,
    timings: Py<PyDict>,
}

impl Features {
    fn from_rust(py: Python<'_>, f: spslam::features::Features) -> PyResult<Self> {
        let n = f.len();
        let dim = f.descriptor_len;
        let shape_error = |e: numpy::ndarray::ShapeError| PyValueError::new_err(e.to_string());
        let xy: Vec<f32> = f.keypoints.iter().flat_map(|k| [k.x, k.y]).collect();
        let keypoints = Array2::from_shape_vec((n, 2), xy).map_err(shape_error)?;
        let column = |get: fn(&spslam::features::Keypoint) -> f32| {
            Array1::from_iter(f.keypoints.iter().map(get))
                .into_pyarray(py)
                .unbind()
        };
        let octaves = Array1::from_iter(f.keypoints.iter().map(|k| k.octave));
        let mut bits = Vec::new();
        pack_sign_bits(&f.descriptors, dim, &mut bits);
        let binary = Array2::from_shape_vec((n, dim.div_ceil(8)), bits).map_err(shape_error)?;
        let descriptors = Array2::from_shape_vec((n, dim), f.descriptors).map_err(shape_error)?;
        let timings = PyDict::new(py);
        let t = &f.timings;
        for (name, ms) in [
            ("preprocess", t.preprocess_ms),
            ("inference", t.inference_ms),
            ("decode_nms", t.decode_nms_ms),
            ("anms", t.anms_ms),
            ("descriptors", t.descriptors_ms),
            ("total", t.total_ms),
        ] {
            timings.set_item(name, ms)?;
        }
        Ok(Self {
            keypoints: keypoints.into_pyarray(py).unbind(),
            scores: column(|k| k.response),
            octaves: octaves.into_pyarray(py).unbind(),
            angles: column(|k| k.angle),
            sizes: column(|k| k.size),
            descriptors: descriptors.into_pyarray(py).unbind(),
            binary_descriptors: binary.into_pyarray(py).unbind(),
            timings: timings.unbind(),
        })
    }
}

#[pymethods]
impl Features {
    /// N×2 `float32`: x, y in pixels of the full-resolution image.
    #[getter]
    fn keypoints(&self, py: Python<'_>) -> Py<PyArray2<f32>> {
        self.keypoints.clone_ref(py)
    }
    /// N `float32`: the detector's score (OpenCV's `response`).
    #[getter]
    fn scores(&self, py: Python<'_>) -> Py<PyArray1<f32>> {
        self.scores.clone_ref(py)
    }
    /// N `int32`: the pyramid level (OpenCV's `octave`).
    #[getter]
    fn octaves(&self, py: Python<'_>) -> Py<PyArray1<i32>> {
        self.octaves.clone_ref(py)
    }
    /// N `float32`: the orientation in degrees (ORB-SLAM3's intensity centroid).
    #[getter]
    fn angles(&self, py: Python<'_>) -> Py<PyArray1<f32>> {
        self.angles.clone_ref(py)
    }
    /// N `float32`: the keypoint's diameter in pixels (OpenCV's `size`).
    #[getter]
    fn sizes(&self, py: Python<'_>) -> Py<PyArray1<f32>> {
        self.sizes.clone_ref(py)
    }
    /// N×256 `float32`, each row of unit L2 norm.
    #[getter]
    fn descriptors(&self, py: Python<'_>) -> Py<PyArray2<f32>> {
        self.descriptors.clone_ref(py)
    }
    /// N×32 `uint8`: the descriptors' sign bits (bit k of byte j is
    /// component 8j+k > 0), the binary view the C ABI and the preload use.
    #[getter]
    fn binary_descriptors(&self, py: Python<'_>) -> Py<PyArray2<u8>> {
        self.binary_descriptors.clone_ref(py)
    }
    /// Stage times in milliseconds.
    #[getter]
    fn timings(&self, py: Python<'_>) -> Py<PyDict> {
        self.timings.clone_ref(py)
    }
    fn __len__(&self, py: Python<'_>) -> usize {
        use numpy::PyUntypedArrayMethods;
        self.scores.bind(py).len()
    }
    fn __repr__(&self, py: Python<'_>) -> String {
        format!("Features({} keypoints)", self.__len__(py))
    }
}
