//! `spslam.match`: brute-force matching with the ratio test and the mutual
//! check (L2 on float descriptors, Hamming on packed binary ones).

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use spslam::features::descriptor_set::ORB_DESCRIPTOR_BYTES;
use spslam::features::DescriptorSet;
use spslam::matching::{match_brute_force, MatchParams};

use crate::errors::match_error;

/// A descriptor block from NumPy: N×D `float32` (L2) or N×32 `uint8` (Hamming).
fn descriptor_set(array: &Bound<'_, PyAny>, what: &str) -> PyResult<DescriptorSet> {
    if let Ok(rows) = array.extract::<PyReadonlyArray2<'_, f32>>() {
        let dim = rows.shape()[1];
        let data = match rows.as_slice() {
            Ok(contiguous) => contiguous.to_vec(),
            Err(_) => rows.as_array().iter().copied().collect(),
        };
        return Ok(DescriptorSet::Float { dim, data });
    }
    if let Ok(rows) = array.extract::<PyReadonlyArray2<'_, u8>>() {
        let width = rows.shape()[1];
        if width != ORB_DESCRIPTOR_BYTES {
            return Err(PyValueError::new_err(format!(
                "{what}: binary descriptors must have {ORB_DESCRIPTOR_BYTES} bytes a row, got {width}"
            )));
        }
        let view = rows.as_array();
        let data = view
            .rows()
            .into_iter()
            .map(|row| {
                let mut bytes = [0u8; ORB_DESCRIPTOR_BYTES];
                for (b, v) in bytes.iter_mut().zip(row.iter()) {
                    *b = *v;
                }
                bytes
            })
            .collect();
        return Ok(DescriptorSet::Binary { data });
    }
    let kind = match array.getattr("dtype") {
        Ok(dtype) => format!(
            "a NumPy array of dtype {} and {} dimensions",
            dtype.str()?,
            array.getattr("ndim")?
        ),
        Err(_) => format!("{}", array.get_type().name()?),
    };
    Err(PyTypeError::new_err(format!(
        "{what} must be an N×D float32 array (L2) or an N×32 uint8 array (Hamming), got {kind}"
    )))
}

/// Matches for Python: M×2 row pairs and M distances.
type MatchArrays<'py> = (Bound<'py, PyArray2<i64>>, Bound<'py, PyArray1<f32>>);

/// Matches every row of `query` against all rows of `train`: Lowe's
/// ratio test (`ratio=None` turns it off), an upper bound on the distance,
/// and the mutual check. Returns `(matches, distances)`: an M×2 `int64`
/// array of (query row, train row) in query order and their M `float32`
/// distances. The GIL is released while matching.
#[pyfunction]
#[pyo3(name = "match", signature = (query, train, *, ratio = Some(0.7), mutual = true, max_distance = None))]
pub fn match_descriptors<'py>(
    py: Python<'py>,
    query: &Bound<'py, PyAny>,
    train: &Bound<'py, PyAny>,
    ratio: Option<f32>,
    mutual: bool,
    max_distance: Option<f32>,
) -> PyResult<MatchArrays<'py>> {
    let query = descriptor_set(query, "query")?;
    let train = descriptor_set(train, "train")?;
    let params = MatchParams {
        ratio,
        max_distance: max_distance.unwrap_or(f32::INFINITY),
        mutual,
    };
    let matches = py
        .detach(|| match_brute_force(&query, &train, params))
        .map_err(match_error)?;
    let pairs: Vec<i64> = matches
        .iter()
        .flat_map(|m| [m.query as i64, m.train as i64])
        .collect();
    let pairs = Array2::from_shape_vec((matches.len(), 2), pairs)
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    let distances: Vec<f32> = matches.iter().map(|m| m.distance).collect();
    Ok((pairs.into_pyarray(py), distances.into_pyarray(py)))
}
