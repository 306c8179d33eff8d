//! `spslam.eval`: the trajectory metrics of `spslam eval` (evo's ATE and
//! RPE, the KITTI devkit's metric) on NumPy arrays or trajectory files.

use std::path::PathBuf;

use nalgebra::Matrix4;
use numpy::ndarray::{Array1, Array3};
use numpy::{
    IntoPyArray, PyArray1, PyArray3, PyReadonlyArray1, PyReadonlyArray3, PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};
use spslam::eval::report::{evaluate as evaluate_report, EvalOptions, Pairing};
use spslam::eval::{
    ate as ate_of, read_kitti_with_times, read_trajectory as read_file, rpe as rpe_of,
    trajectory_from_matrices, Alignment, RpeDelta, RpeOptions, Trajectory, TrajectoryFormat,
};

use crate::errors::eval_error;

/// A trajectory argument: whether its stamps are real times (files with
/// stamps, `(timestamps, poses)` tuples) or frame indices (KITTI files,
/// bare pose arrays).
pub struct Input {
    trajectory: Trajectory,
    timed: bool,
}

fn matrices_from_numpy(poses: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<Matrix4<f64>>> {
    let array: PyReadonlyArray3<'_, f64> = poses.extract().map_err(|_| {
        PyTypeError::new_err(format!(
            "{what}: poses must be a float64 NumPy array of shape N×4×4 or N×3×4"
        ))
    })?;
    let shape = array.shape().to_vec();
    if !(shape[1] == 3 || shape[1] == 4) || shape[2] != 4 {
        return Err(PyValueError::new_err(format!(
            "{what}: poses have shape {shape:?}; give N×4×4 or N×3×4"
        )));
    }
    let view = array.as_array();
    Ok((0..shape[0])
        .map(|i| {
            let mut m = Matrix4::identity();
            for r in 0..shape[1] {
                for c in 0..4 {
                    m[(r, c)] = view[[i, r, c]];
                }
            }
            m
        })
        .collect())
}

/// Reads a trajectory argument: a path (str or os.PathLike; the format is
/// detected), an N×4×4 / N×3×4 array of poses, or `(timestamps, poses)`.
pub fn trajectory_argument(value: &Bound<'_, PyAny>, what: &str) -> PyResult<Input> {
    if let Ok(path) = value.extract::<PathBuf>() {
        let format = TrajectoryFormat::detect(&path).map_err(eval_error)?;
        let trajectory = read_file(&path, format).map_err(eval_error)?;
        return Ok(Input {
            trajectory,
            timed: format != TrajectoryFormat::Kitti,
        });
    }
    if let Ok(tuple) = value.cast::<PyTuple>() {
        if tuple.len() == 2 {
            let stamps: PyReadonlyArray1<'_, f64> = tuple.get_item(0)?.extract().map_err(|_| {
                PyTypeError::new_err(format!("{what}: timestamps must be a float64 NumPy array"))
            })?;
            let stamps = stamps.as_array().to_vec();
            let matrices = matrices_from_numpy(&tuple.get_item(1)?, what)?;
            let trajectory =
                trajectory_from_matrices(matrices, Some(stamps)).map_err(eval_error)?;
            return Ok(Input {
                trajectory,
                timed: true,
            });
        }
    }
    if value.hasattr("shape")? {
        let matrices = matrices_from_numpy(value, what)?;
        let trajectory = trajectory_from_matrices(matrices, None).map_err(eval_error)?;
        return Ok(Input {
            trajectory,
            timed: false,
        });
    }
    Err(PyTypeError::new_err(format!(
        "{what} must be a trajectory file's path, an N×4×4 pose array or a (timestamps, poses) tuple"
    )))
}

/// A trajectory for Python: N timestamps and N×4×4 poses.
pub type TrajectoryArrays<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray3<f64>>);

/// Timestamps and 4×4 pose matrices as NumPy arrays.
pub fn trajectory_arrays<'py>(
    py: Python<'py>,
    timestamps: Vec<f64>,
    matrices: &[Matrix4<f64>],
) -> TrajectoryArrays<'py> {
    let poses = Array3::from_shape_fn((matrices.len(), 4, 4), |(i, r, c)| matrices[i][(r, c)]);
    (
        Array1::from_vec(timestamps).into_pyarray(py),
        poses.into_pyarray(py),
    )
}

/// Pose i with pose i when neither side has real times; else evo's
/// association of the nearest stamps within `max_diff` seconds.
fn pairing(reference: &Input, estimate: &Input, max_diff: f64) -> Pairing {
    if reference.timed && estimate.timed {
        Pairing::ByTimestamp {
            max_diff,
            one_to_one: true,
        }
    } else {
        Pairing::ByIndex
    }
}

/// Converts a serialisable report into Python objects (dicts, lists, floats).
fn to_python<'py>(py: Python<'py>, value: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
    use serde_json::Value;
    Ok(match value {
        Value::Null => py.None().into_bound(py),
        Value::Bool(b) => b.into_pyobject(py)?.to_owned().into_any(),
        Value::Number(n) => match (n.as_i64(), n.as_f64()) {
            (Some(i), _) => i.into_pyobject(py)?.into_any(),
            (None, Some(f)) => f.into_pyobject(py)?.into_any(),
            (None, None) => py.None().into_bound(py),
        },
        Value::String(s) => s.into_pyobject(py)?.into_any(),
        Value::Array(items) => {
            let list = PyList::empty(py);
            for item in items {
                list.append(to_python(py, item)?)?;
            }
            list.into_any()
        }
        Value::Object(map) => {
            let dict = PyDict::new(py);
            for (k, v) in map {
                dict.set_item(k, to_python(py, v)?)?;
            }
            dict.into_any()
        }
    })
}

fn serialised<'py>(py: Python<'py>, value: &impl serde::Serialize) -> PyResult<Bound<'py, PyAny>> {
    let json = serde_json::to_value(value).map_err(|e| PyValueError::new_err(e.to_string()))?;
    to_python(py, &json)
}

/// Reads a trajectory file (KITTI, TUM or EuRoC, detected unless `format`
/// is given; a KITTI file with its `times` file). Returns `(timestamps,
/// poses)`: N `float64` seconds (frame indices for KITTI without times) and
/// N×4×4 `float64` poses.
#[pyfunction]
#[pyo3(signature = (path, *, format = None, times = None))]
pub fn read_trajectory<'py>(
    py: Python<'py>,
    path: PathBuf,
    format: Option<&str>,
    times: Option<PathBuf>,
) -> PyResult<TrajectoryArrays<'py>> {
    let format = match format {
        Some(name) => name.parse::<TrajectoryFormat>().map_err(eval_error)?,
        None => TrajectoryFormat::detect(&path).map_err(eval_error)?,
    };
    let trajectory = match (format, times) {
        (TrajectoryFormat::Kitti, Some(times)) => read_kitti_with_times(&path, &times),
        (_, Some(_)) => {
            return Err(PyValueError::new_err(format!(
                "a times file only applies to KITTI files ({})",
                path.display()
            )))
        }
        (format, None) => read_file(&path, format),
    }
    .map_err(eval_error)?;
    let matrices = trajectory.matrices();
    Ok(trajectory_arrays(py, trajectory.timestamps, &matrices))
}

/// Everything `spslam eval --json` reports (ATE under no/SE3/Sim3
/// alignment, RPE, the KITTI metric when the ground truth is long enough),
/// as a dict. Poses pair by index unless both sides carry timestamps.
#[pyfunction]
#[pyo3(signature = (reference, estimate, *, max_diff = 0.01))]
pub fn evaluate<'py>(
    py: Python<'py>,
    reference: &Bound<'py, PyAny>,
    estimate: &Bound<'py, PyAny>,
    max_diff: f64,
) -> PyResult<Bound<'py, PyAny>> {
    let reference = trajectory_argument(reference, "reference")?;
    let estimate = trajectory_argument(estimate, "estimate")?;
    let options = EvalOptions {
        pairing: pairing(&reference, &estimate, max_diff),
        ..EvalOptions::default()
    };
    let report = py
        .detach(|| evaluate_report(&reference.trajectory, &estimate.trajectory, &options))
        .map_err(eval_error)?;
    serialised(py, &report)
}

/// Reads both trajectory arguments and pairs their poses (see [`pairing`]).
fn paired(
    reference: &Bound<'_, PyAny>,
    estimate: &Bound<'_, PyAny>,
    max_diff: f64,
) -> PyResult<spslam::eval::AssociatedPair> {
    let reference = trajectory_argument(reference, "reference")?;
    let estimate = trajectory_argument(estimate, "estimate")?;
    spslam::eval::report::pair_trajectories(
        &reference.trajectory,
        &estimate.trajectory,
        pairing(&reference, &estimate, max_diff),
    )
    .map_err(eval_error)
}

/// evo's APE on positions (`evo_ape -a` for `"se3"`, `-as` for `"sim3"`,
/// none for `"none"`): a dict of rmse, mean, median, std, min, max, count
/// and the Sim3 scale.
#[pyfunction]
#[pyo3(signature = (reference, estimate, *, alignment = "se3", max_diff = 0.01))]
pub fn ate<'py>(
    py: Python<'py>,
    reference: &Bound<'py, PyAny>,
    estimate: &Bound<'py, PyAny>,
    alignment: &str,
    max_diff: f64,
) -> PyResult<Bound<'py, PyAny>> {
    let alignment = match alignment.to_ascii_lowercase().as_str() {
        "none" => Alignment::None,
        "se3" => Alignment::Se3,
        "sim3" => Alignment::Sim3,
        other => {
            return Err(PyValueError::new_err(format!(
                "alignment {other:?}: give \"none\", \"se3\" or \"sim3\""
            )))
        }
    };
    let pair = paired(reference, estimate, max_diff)?;
    let result = ate_of(&pair.reference, &pair.estimate, alignment).map_err(eval_error)?;
    serialised(py, &result)
}

/// evo's RPE (`evo_rpe`, translation and rotation parts) for pairs `delta`
/// frames (`unit="frames"`) or metres of path (`unit="meters"`) apart;
/// `None` when no pair fits.
#[pyfunction]
#[pyo3(signature = (reference, estimate, *, delta = 1.0, unit = "frames", all_pairs = false, max_diff = 0.01))]
pub fn rpe<'py>(
    py: Python<'py>,
    reference: &Bound<'py, PyAny>,
    estimate: &Bound<'py, PyAny>,
    delta: f64,
    unit: &str,
    all_pairs: bool,
    max_diff: f64,
) -> PyResult<Bound<'py, PyAny>> {
    let delta = match unit {
        "frames" if delta >= 1.0 && delta.fract() == 0.0 => RpeDelta::Frames(delta as usize),
        "meters" if delta > 0.0 && delta.is_finite() => RpeDelta::Meters(delta),
        _ => {
            return Err(PyValueError::new_err(format!(
                "delta {delta} {unit}: give a whole number of frames ≥ 1 (unit=\"frames\") or a positive length (unit=\"meters\")"
            )))
        }
    };
    let pair = paired(reference, estimate, max_diff)?;
    let options = RpeOptions {
        all_pairs,
        ..RpeOptions::new(delta)
    };
    let result = rpe_of(&pair.reference, &pair.estimate, options).map_err(eval_error)?;
    serialised(py, &result)
}

/// The KITTI odometry devkit's metric (translation % and rotation deg/m
/// over 100–800 m segments); `None` when the path is shorter than 100 m.
/// Poses pair by index.
#[pyfunction]
pub fn kitti_metric<'py>(
    py: Python<'py>,
    reference: &Bound<'py, PyAny>,
    estimate: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    let reference = trajectory_argument(reference, "reference")?;
    let estimate = trajectory_argument(estimate, "estimate")?;
    let metric = spslam::eval::kitti_metric(&reference.trajectory, &estimate.trajectory)
        .map_err(eval_error)?;
    serialised(py, &metric)
}
