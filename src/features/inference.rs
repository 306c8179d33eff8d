//! Where and at what precision the network runs: [`Precision`] picks the
//! model file, [`Device`] the ONNX Runtime execution provider.

use std::path::PathBuf;

use super::FeatureError;

/// The numeric precision of the SuperPoint network.
///
/// The two precisions are two model files written by `make setup`:
/// `models/superpoint.onnx` (fp32, `tools/export_superpoint.py`) and
/// `models/superpoint_int8.onnx` (BatchNorm folded through the ReLUs, then
/// static QDQ u8 quantisation, `tools/quantize_superpoint.py`).
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum Precision {
    /// 32-bit floats everywhere: the exact network.
    Fp32,
    /// 8-bit convolutions (the 1×1 heads and the output tail stay fp32):
    /// about 3× faster on a CPU; the default everywhere (library, C ABI,
    /// settings, CLI). Away from a 40 px border band the descriptors are
    /// within a cosine of 0.996 of fp32's; in that band the BatchNorm fold's
    /// zero padding moves them (cosine ~0.85), see `tools/quantize_superpoint.py`.
    #[default]
    Int8,
}

impl Precision {
    /// The model file used when none is given: the environment variable
    /// (`SPSLAM_MODEL` for fp32, `SPSLAM_MODEL_INT8` for int8), else the file
    /// under `models/` in the crate root, where `make setup` writes it.
    pub fn default_model_path(self) -> PathBuf {
        let (variable, file) = match self {
            Precision::Fp32 => ("SPSLAM_MODEL", "superpoint.onnx"),
            Precision::Int8 => ("SPSLAM_MODEL_INT8", "superpoint_int8.onnx"),
        };
        std::env::var_os(variable)
            .filter(|p| !p.is_empty())
            .map(PathBuf::from)
            .unwrap_or_else(|| {
                PathBuf::from(env!("CARGO_MANIFEST_DIR"))
                    .join("models")
                    .join(file)
            })
    }

    /// The name used in settings files and on the command line.
    pub fn as_str(self) -> &'static str {
        match self {
            Precision::Fp32 => "fp32",
            Precision::Int8 => "int8",
        }
    }
}

impl std::str::FromStr for Precision {
    type Err = FeatureError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.to_ascii_lowercase().as_str() {
            "fp32" => Ok(Precision::Fp32),
            "int8" => Ok(Precision::Int8),
            _ => Err(FeatureError::InvalidConfig {
                name: "precision",
                value: s.to_string(),
                expected: "fp32 or int8",
            }),
        }
    }
}

impl std::fmt::Display for Precision {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Where ONNX Runtime runs the network.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum Device {
    /// CUDA when the loaded ONNX Runtime library offers it and a session can
    /// be created on it (the GPU build from `make setup-gpu` on a machine
    /// with an NVIDIA GPU), else the CPU. With the CPU build of `make setup`
    /// this is the CPU.
    #[default]
    Auto,
    /// The CPU execution provider.
    Cpu,
    /// ONNX Runtime's CUDA execution provider; an error
    /// ([`FeatureError::DeviceUnavailable`]) when it cannot be used.
    Cuda,
}

impl Device {
    /// The name used in settings files and on the command line.
    pub fn as_str(self) -> &'static str {
        match self {
            Device::Auto => "auto",
            Device::Cpu => "cpu",
            Device::Cuda => "cuda",
        }
    }
}

impl std::str::FromStr for Device {
    type Err = FeatureError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.to_ascii_lowercase().as_str() {
            "auto" => Ok(Device::Auto),
            "cpu" => Ok(Device::Cpu),
            "cuda" => Ok(Device::Cuda),
            _ => Err(FeatureError::InvalidConfig {
                name: "device",
                value: s.to_string(),
                expected: "auto, cpu or cuda",
            }),
        }
    }
}

impl std::fmt::Display for Device {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_bad_names_say_what_is_accepted() {
        for p in [Precision::Fp32, Precision::Int8] {
            assert_eq!(p.as_str().parse::<Precision>().ok(), Some(p));
        }
        for d in [Device::Auto, Device::Cpu, Device::Cuda] {
            assert_eq!(d.to_string().parse::<Device>().ok(), Some(d));
        }
        let err = "int4".parse::<Precision>().err().map(|e| e.to_string());
        assert!(err.is_some_and(|e| e.contains("fp32 or int8")));
        let err = "tpu".parse::<Device>().err().map(|e| e.to_string());
        assert!(err.is_some_and(|e| e.contains("auto, cpu or cuda")));
    }

    #[test]
    fn each_precision_has_its_own_default_model() {
        let fp32 = Precision::Fp32.default_model_path();
        let int8 = Precision::Int8.default_model_path();
        assert_ne!(fp32, int8);
    }
}
