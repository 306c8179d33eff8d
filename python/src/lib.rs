//! `spslam._spslam`: the extension module behind the `spslam` Python
//! package (`python/spslam/`). No panic crosses into Python: pyo3 turns a
//! panic into `pyo3_runtime.PanicException`, and every error path here
//! returns a Python exception with the Rust error's message.

use pyo3::prelude::*;

mod errors;
mod extractor;
mod image;
mod matcher;
mod metrics;
mod system;

/// The extension module.
#[pymodule]
fn _spslam(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("SpslamError", m.py().get_type::<errors::SpslamError>())?;
    m.add_class::<extractor::Extractor>()?;
    m.add_class::<extractor::Features>()?;
    m.add_class::<system::System>()?;
    m.add_function(wrap_pyfunction!(matcher::match_descriptors, m)?)?;
    m.add_function(wrap_pyfunction!(metrics::read_trajectory, m)?)?;
    m.add_function(wrap_pyfunction!(metrics::evaluate, m)?)?;
    m.add_function(wrap_pyfunction!(metrics::ate, m)?)?;
    m.add_function(wrap_pyfunction!(metrics::rpe, m)?)?;
    m.add_function(wrap_pyfunction!(metrics::kitti_metric, m)?)?;
    Ok(())
}
