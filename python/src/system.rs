//! `spslam.System`: stereo, RGB-D and monocular SLAM from Python, shaped
//! like the `orbslam3-python` bindings (`process_image_*`, `shutdown`),
//! with `track_*` returning the camera pose.

use std::path::PathBuf;
use std::sync::Mutex;

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use spslam::camera::{DepthImage, Sensor};
use spslam::features::GrayImage;
use spslam::optim::Se3;
use spslam::settings::SlamSettings;
use spslam::storage::{DescriptorPrecision, LoadedAtlas, SaveOptions};
use spslam::system::{
    assemble_system, ExtractorKind, LoadedMapUse, MapProvenance, SlamSystem, SystemOptions,
};
use spslam::tracking::{SensorImages, TrackingState};

use crate::errors::{feature_error, SpslamError};
use crate::image::gray_from_numpy;
use crate::metrics::{trajectory_arrays, TrajectoryArrays};

/// The ORB-SLAM3 `DepthMapFactor` used when the settings give none (TUM's 5000).
const DEFAULT_DEPTH_MAP_FACTOR: f64 = 5000.0;

/// A map file read by `load_map`, applied when the system is built (on
/// the first frame, when the image size is known).
struct PendingMap {
    path: PathBuf,
    loaded: LoadedAtlas,
    localize: bool,
}

struct State {
    settings: SlamSettings,
    sensor: Sensor,
    options: SystemOptions,
    inline_mapping: bool,
    slam: Option<(SlamSystem, MapProvenance, (usize, usize))>,
    pending_map: Option<PendingMap>,
    frames: usize,
    shut_down: bool,
}

/// SLAM over frames given one at a time (see the class docstring in the stubs).
#[pyclass(module = "spslam", name = "System")]
pub struct System {
    state: Mutex<State>,
}

fn slam_error(e: spslam::error::SlamError) -> PyErr {
    use spslam::error::SlamError as E;
    match e {
        E::Extractor { source } => feature_error(source),
        E::InvalidCamera { .. }
        | E::DepthSizeMismatch { .. }
        | E::SensorMismatch { .. }
        | E::ImageSizeMismatch { .. } => PyValueError::new_err(e.to_string()),
        other => SpslamError::new_err(other.to_string()),
    }
}

fn pose_matrix(pose: &Se3) -> Array2<f64> {
    let m = pose.to_isometry().to_homogeneous();
    Array2::from_shape_fn((4, 4), |(r, c)| m[(r, c)])
}

fn depth_image(depth: &Bound<'_, PyAny>, factor: f64) -> PyResult<DepthImage> {
    let shape_error =
        |shape: &[usize]| PyValueError::new_err(format!("depth has shape {shape:?}; give H×W"));
    let depth_error = |e: spslam::camera::DepthError| PyValueError::new_err(e.to_string());
    if let Ok(raw) = depth.extract::<PyReadonlyArray2<'_, u16>>() {
        let (h, w) = (raw.shape()[0], raw.shape()[1]);
        let values: Vec<u16> = raw.as_array().iter().copied().collect();
        return DepthImage::from_raw(&values, w, h, factor).map_err(depth_error);
    }
    if let Ok(raw) = depth.extract::<PyReadonlyArray2<'_, f32>>() {
        let (h, w) = (raw.shape()[0], raw.shape()[1]);
        let values: Vec<f32> = raw.as_array().iter().copied().collect();
        return DepthImage::from_raw(&values, w, h, factor).map_err(depth_error);
    }
    if let Ok(shape) = depth
        .getattr("shape")
        .and_then(|s| s.extract::<Vec<usize>>())
    {
        if shape.len() != 2 {
            return Err(shape_error(&shape));
        }
    }
    let kind = match depth.getattr("dtype") {
        Ok(dtype) => format!("dtype {}", dtype.str()?),
        Err(_) => format!("{}", depth.get_type().name()?),
    };
    Err(PyTypeError::new_err(format!(
        "depth must be a NumPy uint16 or float32 array (H×W, raw values divided by DepthMapFactor), got {kind}"
    )))
}

/// One frame's images, owned, ready to hand to the system without the GIL.
enum Images {
    Monocular(GrayImage),
    Stereo(GrayImage, GrayImage),
    Rgbd(GrayImage, DepthImage),
}

impl Images {
    fn views(&self) -> SensorImages<'_> {
        match self {
            Images::Monocular(image) => SensorImages::Monocular(image.view()),
            Images::Stereo(left, right) => SensorImages::Stereo {
                left: left.view(),
                right: right.view(),
            },
            Images::Rgbd(image, depth) => SensorImages::Rgbd {
                image: image.view(),
                depth,
            },
        }
    }
    fn sensor(&self) -> Sensor {
        match self {
            Images::Monocular(_) => Sensor::Monocular,
            Images::Stereo(..) => Sensor::Stereo,
            Images::Rgbd(..) => Sensor::Rgbd,
        }
    }
    fn size(&self) -> (usize, usize) {
        let image = match self {
            Images::Monocular(image) | Images::Stereo(image, _) | Images::Rgbd(image, _) => image,
        };
        (image.width(), image.height())
    }
}

impl State {
    /// Builds the system on the first frame (the image size is needed).
    fn system(&mut self, size: (usize, usize)) -> Result<&mut SlamSystem, PyErr> {
        if self.shut_down {
            return Err(SpslamError::new_err(
                "the system was shut down; create a new System",
            ));
        }
        if let Some((_, _, built)) = &self.slam {
            if *built != size {
                return Err(PyValueError::new_err(format!(
                    "the image is {}x{}; this system was started on {}x{} images",
                    size.0, size.1, built.0, built.1
                )));
            }
        } else {
            let assembled = assemble_system(&self.settings, self.sensor, size, &self.options)
                .map_err(slam_error)?;
            let mut slam = assembled.system;
            if let Some(pending) = self.pending_map.take() {
                let use_ = if pending.localize {
                    LoadedMapUse::LocaliseOnly
                } else {
                    LoadedMapUse::ContinueMapping
                };
                slam.load_map(&pending.path, pending.loaded, &assembled.provenance, use_)
                    .map_err(slam_error)?;
            }
            if !self.inline_mapping {
                slam.spawn_mapping_thread().map_err(slam_error)?;
            }
            self.slam = Some((slam, assembled.provenance, size));
        }
        match &mut self.slam {
            Some((slam, _, _)) => Ok(slam),
            None => Err(SpslamError::new_err("the system could not be built")),
        }
    }
}

impl System {
    fn locked(&self) -> PyResult<std::sync::MutexGuard<'_, State>> {
        self.state
            .lock()
            .map_err(|_| SpslamError::new_err("the system failed in another thread"))
    }

    /// Tracks one frame; the GIL is released meanwhile.
    fn track(
        &self,
        py: Python<'_>,
        images: Images,
        timestamp: f64,
    ) -> PyResult<Option<Array2<f64>>> {
        if !timestamp.is_finite() {
            return Err(PyValueError::new_err(format!(
                "timestamp {timestamp} is not a finite number of seconds"
            )));
        }
        py.detach(|| {
            let mut state = self.locked()?;
            if images.sensor() != state.sensor {
                return Err(PyValueError::new_err(format!(
                    "this system was created for {} frames; use track_{}",
                    state.sensor.as_str(),
                    match state.sensor {
                        Sensor::Monocular => "monocular",
                        Sensor::Stereo => "stereo",
                        Sensor::Rgbd => "rgbd",
                    }
                )));
            }
            let index = state.frames;
            let slam = state.system(images.size())?;
            slam.process_images(index, timestamp, images.views())
                .map_err(slam_error)?;
            let pose = slam.last_pose().map_err(slam_error)?;
            state.frames += 1;
            Ok(pose.as_ref().map(pose_matrix))
        })
    }
}

fn extractor_kind(name: &str) -> PyResult<ExtractorKind> {
    match name.to_ascii_lowercase().as_str() {
        "superpoint" => Ok(ExtractorKind::SuperPoint),
        "orb" => Ok(ExtractorKind::Orb),
        other => Err(PyValueError::new_err(format!(
            "extractor {other:?}: give \"superpoint\" or \"orb\""
        ))),
    }
}

#[pymethods]
impl System {
    /// Reads the ORB-SLAM3 settings file; the system itself (extractors,
    /// threads) is built on the first frame.
    #[new]
    #[pyo3(signature = (
        settings,
        sensor = "stereo",
        *,
        extractor = "superpoint",
        levels = None,
        model = None,
        precision = None,
        loop_closing = true,
        codebook = None,
        inline_mapping = false,
    ))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        settings: PathBuf,
        sensor: &str,
        extractor: &str,
        levels: Option<usize>,
        model: Option<PathBuf>,
        precision: Option<&str>,
        loop_closing: bool,
        codebook: Option<PathBuf>,
        inline_mapping: bool,
    ) -> PyResult<Self> {
        let sensor: Sensor = sensor
            .parse()
            .map_err(|e: spslam::camera::UnknownSensor| PyValueError::new_err(e.to_string()))?;
        let mut settings = SlamSettings::from_file(&settings).map_err(|e| {
            let message = format!("{}: {e}", settings.display());
            if settings.is_file() {
                PyValueError::new_err(message)
            } else {
                pyo3::exceptions::PyFileNotFoundError::new_err(message)
            }
        })?;
        if let Some(model) = model {
            settings.extractor.model = Some(model);
        }
        if let Some(precision) = precision {
            settings.extractor.precision = precision.parse().map_err(feature_error)?;
        }
        Ok(Self {
            state: Mutex::new(State {
                settings,
                sensor,
                options: SystemOptions {
                    extractor: extractor_kind(extractor)?,
                    levels,
                    loop_closing,
                    codebook,
                    ..SystemOptions::default()
                },
                inline_mapping,
                slam: None,
                pending_map: None,
                frames: 0,
                shut_down: false,
            }),
        })
    }

    /// Tracks a rectified stereo pair; returns the left camera's pose
    /// `T_wc` (4×4, camera to world) or `None` when the frame was not tracked.
    #[pyo3(signature = (left, right, timestamp, *, rgb = false))]
    fn track_stereo<'py>(
        &self,
        py: Python<'py>,
        left: &Bound<'py, PyAny>,
        right: &Bound<'py, PyAny>,
        timestamp: f64,
        rgb: bool,
    ) -> PyResult<Option<Bound<'py, PyArray2<f64>>>> {
        let images = Images::Stereo(
            gray_from_numpy(left, "left", rgb)?,
            gray_from_numpy(right, "right", rgb)?,
        );
        Ok(self
            .track(py, images, timestamp)?
            .map(|m| m.into_pyarray(py)))
    }

    /// Tracks an image and its registered depth (`uint16` or `float32`
    /// raw values; metres = value / the settings' `DepthMapFactor`).
    #[pyo3(signature = (image, depth, timestamp, *, rgb = false))]
    fn track_rgbd<'py>(
        &self,
        py: Python<'py>,
        image: &Bound<'py, PyAny>,
        depth: &Bound<'py, PyAny>,
        timestamp: f64,
        rgb: bool,
    ) -> PyResult<Option<Bound<'py, PyArray2<f64>>>> {
        let factor = self
            .locked()?
            .settings
            .depth_map_factor
            .unwrap_or(DEFAULT_DEPTH_MAP_FACTOR);
        let images = Images::Rgbd(
            gray_from_numpy(image, "image", rgb)?,
            depth_image(depth, factor)?,
        );
        Ok(self
            .track(py, images, timestamp)?
            .map(|m| m.into_pyarray(py)))
    }

    /// Tracks one image (monocular: the map's scale is arbitrary).
    #[pyo3(signature = (image, timestamp, *, rgb = false))]
    fn track_monocular<'py>(
        &self,
        py: Python<'py>,
        image: &Bound<'py, PyAny>,
        timestamp: f64,
        rgb: bool,
    ) -> PyResult<Option<Bound<'py, PyArray2<f64>>>> {
        let images = Images::Monocular(gray_from_numpy(image, "image", rgb)?);
        Ok(self
            .track(py, images, timestamp)?
            .map(|m| m.into_pyarray(py)))
    }

    /// `orbslam3-python`'s name: tracks a stereo pair, returns whether it was tracked.
    fn process_image_stereo(
        &self,
        py: Python<'_>,
        left: &Bound<'_, PyAny>,
        right: &Bound<'_, PyAny>,
        timestamp: f64,
    ) -> PyResult<bool> {
        Ok(self
            .track_stereo(py, left, right, timestamp, false)?
            .is_some())
    }

    /// `orbslam3-python`'s name: tracks an RGB-D frame, returns whether it was tracked.
    fn process_image_rgbd(
        &self,
        py: Python<'_>,
        image: &Bound<'_, PyAny>,
        depth: &Bound<'_, PyAny>,
        timestamp: f64,
    ) -> PyResult<bool> {
        Ok(self
            .track_rgbd(py, image, depth, timestamp, false)?
            .is_some())
    }

    /// `orbslam3-python`'s name: tracks one image, returns whether it was tracked.
    fn process_image_mono(
        &self,
        py: Python<'_>,
        image: &Bound<'_, PyAny>,
        timestamp: f64,
    ) -> PyResult<bool> {
        Ok(self.track_monocular(py, image, timestamp, false)?.is_some())
    }

    /// `"not_initialised"`, `"ok"` or `"lost"`.
    #[getter]
    fn tracking_state(&self) -> PyResult<&'static str> {
        let state = self.locked()?;
        Ok(match state.slam.as_ref().map(|(slam, _, _)| slam.state()) {
            None | Some(TrackingState::NotInitialised) => "not_initialised",
            Some(TrackingState::Ok) => "ok",
            Some(TrackingState::Lost) => "lost",
        })
    }

    /// Every frame's `(timestamps, poses)`: N seconds and N×4×4 `T_wc`,
    /// as `spslam run` writes them (a frame without a pose repeats the
    /// previous one; later maps anchored where the previous one left off).
    /// The poses reflect the latest loop corrections and bundle adjustments.
    fn trajectory<'py>(&self, py: Python<'py>) -> PyResult<TrajectoryArrays<'py>> {
        let state = self.locked()?;
        let poses = match &state.slam {
            Some((slam, _, _)) => slam.trajectory().map_err(slam_error)?,
            None => Vec::new(),
        };
        let matrices: Vec<_> = poses
            .iter()
            .map(|(_, pose)| pose.to_isometry().to_homogeneous())
            .collect();
        let stamps = poses.iter().map(|(t, _)| *t).collect();
        Ok(trajectory_arrays(py, stamps, &matrices))
    }

    /// Writes the atlas to a map file (`precision`: descriptors as
    /// `"f32"`, `"f16"` or `"u8"`); returns (keyframes, map points, bytes).
    #[pyo3(signature = (path, *, precision = "f16"))]
    fn save_map(
        &self,
        py: Python<'_>,
        path: PathBuf,
        precision: &str,
    ) -> PyResult<(usize, usize, u64)> {
        let precision: DescriptorPrecision = precision.parse().map_err(PyValueError::new_err)?;
        py.detach(|| {
            let state = self.locked()?;
            let Some((slam, provenance, _)) = &state.slam else {
                return Err(SpslamError::new_err(
                    "no frame was tracked yet: there is no map to save",
                ));
            };
            let saved = slam
                .save_map(&path, provenance, precision, SaveOptions::default())
                .map_err(slam_error)?;
            Ok((saved.keyframes, saved.points, saved.bytes))
        })
    }

    /// Reads a map file saved by `save_map` or `spslam run --save-map`;
    /// it is used from the first frame on (`localize=True`: tracking only,
    /// the map is not changed). Call before the first frame. Tracking
    /// starts lost and finds the map through place recognition (on with
    /// loop closing); without it, only the map's 30 newest keyframes are tried.
    #[pyo3(signature = (path, *, localize = false))]
    fn load_map(&self, py: Python<'_>, path: PathBuf, localize: bool) -> PyResult<()> {
        py.detach(|| {
            let mut state = self.locked()?;
            if state.slam.is_some() {
                return Err(SpslamError::new_err(
                    "load_map must come before the first frame (the map is loaded when the system starts)",
                ));
            }
            let loaded = spslam::storage::load(&path).map_err(|e| {
                let message = format!("cannot load the map {}: {e}", path.display());
                if path.exists() {
                    SpslamError::new_err(message)
                } else {
                    pyo3::exceptions::PyFileNotFoundError::new_err(message)
                }
            })?;
            state.pending_map = Some(PendingMap {
                path,
                loaded,
                localize,
            });
            Ok(())
        })
    }

    /// Lets local mapping finish its queue and stops the threads. The
    /// trajectory and the map stay readable; tracking more frames is an error.
    fn shutdown(&self, py: Python<'_>) -> PyResult<()> {
        py.detach(|| {
            let mut state = self.locked()?;
            state.shut_down = true;
            match &mut state.slam {
                Some((slam, _, _)) => slam.finish().map_err(slam_error),
                None => Ok(()),
            }
        })
    }

    /// Frames given so far.
    #[getter]
    fn frames(&self) -> PyResult<usize> {
        Ok(self.locked()?.frames)
    }

    fn __enter__(slf: Py<Self>) -> Py<Self> {
        slf
    }

    fn __exit__(
        &self,
        py: Python<'_>,
        _kind: &Bound<'_, PyAny>,
        _value: &Bound<'_, PyAny>,
        _traceback: &Bound<'_, PyAny>,
    ) -> PyResult<bool> {
        self.shutdown(py)?;
        Ok(false)
    }
}
