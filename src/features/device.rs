//! Where ONNX Runtime runs the network: the device a user chooses
//! (`--device`, `SuperPoint.device`, the C ABI's config).

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
    /// ([`super::FeatureError::DeviceUnavailable`]) when it cannot be used.
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

impl std::fmt::Display for Device {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}
