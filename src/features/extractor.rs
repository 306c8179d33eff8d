//! The SuperPoint + ANMS extractor: pyramid → network → periodic filter + NMS →
//! ANMS → descriptors, with ORB-SLAM3's per-level quotas and keypoint fields.

use std::time::Instant;

use ndarray::{ArrayView2, ArrayView4};

use super::anms::{self, Candidate};
use super::exposure::ExposureStretch;
use super::image::MIN_IMAGE_SIDE;
use super::model::{fill_padded_input_stretched, SuperPointModel};
use super::nms::{nms_candidates, ValidRegion};
use super::orientation::{CircularPatch, PATCH_SIZE};
use super::periodic::{reject_excess_phases, reject_low_contrast, LatticeMask};
use super::pyramid::{build_pyramid, ScaleTables};
use super::{
    Device, ExtractorConfig, FeatureError, Features, GrayImageView, Keypoint, PeriodicFilterConfig,
    Precision, StageTimings,
};

/// What the periodic-artefact filter did on one extraction (for diagnostics).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PeriodicFilterReport {
    /// Cells cleared as part of an 8-px lattice, over all levels.
    pub lattice_cells: usize,
    /// Candidates dropped for low contrast, over all levels.
    pub low_contrast_rejected: usize,
    /// Candidates dropped on an excess sub-cell phase, over all levels.
    pub excess_phase_rejected: usize,
}

/// Reusable buffers, so repeated extractions do not allocate anew.
#[derive(Default)]
struct Scratch {
    cell_max: Vec<(u8, f32)>,
    descriptor: Vec<f32>,
    points: Vec<(f32, f32)>,
}

/// SuperPoint keypoints and descriptors, spread by ANMS, with ORB-SLAM3's
/// pyramid semantics. One instance is not shared between threads; create one
/// per thread (two extractors run in parallel fine).
pub struct SuperPointExtractor {
    config: ExtractorConfig,
    tables: ScaleTables,
    model: SuperPointModel,
    patch: CircularPatch,
    input: Vec<f32>,
    scratch: Scratch,
    last_report: PeriodicFilterReport,
    last_exposure: ExposureStretch,
}

impl std::fmt::Debug for SuperPointExtractor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SuperPointExtractor")
            .field("config", &self.config)
            .field("model", &self.model)
            .finish()
    }
}

impl SuperPointExtractor {
    /// Validates the config, loads ONNX Runtime and the model. A model whose
    /// metadata says it has no grid artefact
    /// ([`SuperPointModel::has_grid_artefact`]) runs without the periodic
    /// filter, whatever `config.periodic_filter.enabled` says; [`config`](Self::config)
    /// shows the filter as it runs.
    pub fn new(mut config: ExtractorConfig) -> Result<Self, FeatureError> {
        config.validate()?;
        // The int8 model's QDQ graph is made for the CPU: `auto` keeps it there.
        let device = match (config.device, config.precision) {
            (Device::Auto, Precision::Int8) => {
                tracing::debug!(
                    "device auto with the int8 model runs on the CPU; choose --precision fp32 for CUDA"
                );
                Device::Cpu
            }
            (device, _) => device,
        };
        let model = SuperPointModel::load(
            &config.resolved_model_path(),
            config.ort_library_path.as_deref(),
            config.threads,
            device,
        )?;
        if !model.has_grid_artefact() {
            config.periodic_filter.enabled = false;
        }
        let tables = ScaleTables::new(config.n_features, config.scale_factor, config.n_levels);
        Ok(Self {
            config,
            tables,
            model,
            patch: CircularPatch::new(),
            input: Vec::new(),
            scratch: Scratch::default(),
            last_report: PeriodicFilterReport::default(),
            last_exposure: ExposureStretch::IDENTITY,
        })
    }

    /// The configuration in use.
    pub fn config(&self) -> &ExtractorConfig {
        &self.config
    }

    /// ORB-SLAM3's scale and sigma² tables and the per-level quotas.
    pub fn scale_tables(&self) -> &ScaleTables {
        &self.tables
    }

    /// Floats per descriptor, read from the model.
    pub fn descriptor_len(&self) -> usize {
        self.model.descriptor_len()
    }

    /// The model's descriptor-distance thresholds
    /// ([`SuperPointModel::distance_thresholds`]).
    pub fn distance_thresholds(&self) -> super::DistanceThresholds {
        self.model.distance_thresholds()
    }

    /// Whether the model's scores carry the grid artefact the periodic
    /// filter removes ([`SuperPointModel::has_grid_artefact`]).
    pub fn model_has_grid_artefact(&self) -> bool {
        self.model.has_grid_artefact()
    }

    /// The device the network runs on (`Cpu` or `Cuda`, `Auto` resolved).
    pub fn device(&self) -> super::Device {
        self.model.device()
    }

    /// What the periodic-artefact filter did on the last extraction.
    pub fn last_periodic_report(&self) -> PeriodicFilterReport {
        self.last_report
    }

    /// The exposure stretch applied on the last extraction (the identity
    /// before the first; see [`exposure`](super::exposure)).
    pub fn last_exposure(&self) -> ExposureStretch {
        self.last_exposure
    }

    /// Direct access to the network, e.g. to time a bare inference.
    pub fn model_mut(&mut self) -> &mut SuperPointModel {
        &mut self.model
    }

    /// Extracts keypoints (level-0 coordinates) and unit-L2 descriptors.
    pub fn extract(&mut self, image: GrayImageView<'_>) -> Result<Features, FeatureError> {
        let (width, height) = (image.width(), image.height());
        if width < MIN_IMAGE_SIDE || height < MIN_IMAGE_SIDE {
            return Err(FeatureError::ImageTooSmall {
                width,
                height,
                min_side: MIN_IMAGE_SIDE,
            });
        }
        let mut timings = StageTimings::default();
        let t = Instant::now();
        let pyramid = if self.tables.n_levels() > 1 {
            build_pyramid(image, &self.tables)?
        } else {
            Vec::new()
        };
        timings.preprocess_ms += ms(t);

        let mut features = Features {
            descriptor_len: self.model.descriptor_len(),
            ..Features::default()
        };
        features.keypoints.reserve(self.config.n_features);
        features
            .descriptors
            .reserve(self.config.n_features * features.descriptor_len);
        self.last_report = PeriodicFilterReport::default();
        let t = Instant::now();
        let stretch = ExposureStretch::measure(image, &self.config.exposure);
        self.last_exposure = stretch;
        timings.preprocess_ms += ms(t);
        for level in 0..self.tables.n_levels() {
            let level_image = match level {
                0 => image,
                _ => match pyramid.get(level) {
                    Some(img) => img.view(),
                    None => break, // the level would be smaller than one pixel
                },
            };
            let quota = self.tables.features_per_level[level];
            if quota == 0
                || level_image.width() < MIN_IMAGE_SIDE
                || level_image.height() < MIN_IMAGE_SIDE
            {
                continue;
            }
            let input = LevelInput {
                level,
                image: level_image,
                stretch,
            };
            self.extract_level(input, quota, &mut features, &mut timings)?;
        }
        timings.total_ms = timings.preprocess_ms
            + timings.inference_ms
            + timings.decode_nms_ms
            + timings.anms_ms
            + timings.descriptors_ms;
        features.timings = timings;
        Ok(features)
    }

    fn extract_level(
        &mut self,
        input: LevelInput<'_>,
        quota: usize,
        features: &mut Features,
        timings: &mut StageTimings,
    ) -> Result<(), FeatureError> {
        let LevelInput {
            level,
            image,
            stretch,
        } = input;
        let t = Instant::now();
        let (pw, ph) = fill_padded_input_stretched(image, stretch, &mut self.input);
        timings.preprocess_ms += ms(t);

        let t_inference = Instant::now();
        let input = ArrayView4::from_shape((1, 1, ph, pw), &self.input)
            .map_err(|e| FeatureError::Runtime(e.to_string()))?;
        let config = &self.config;
        let scratch = &mut self.scratch;
        let patch = &self.patch;
        let scale = self.tables.scale_factors[level];
        let report = &mut self.last_report;
        let region = ValidRegion {
            width: image.width(),
            height: image.height(),
            border: config.border,
        };
        self.model.run(input, |scores, desc| {
            timings.inference_ms += ms(t_inference);

            let t = Instant::now();
            // As ORB-SLAM3 retries FAST with minThFAST: the fallbacks are tried
            // only while the level has fewer candidates than its quota.
            let detect = |threshold, radius, cell_max: &mut Vec<(u8, f32)>| {
                let pass = DetectionPass {
                    threshold,
                    radius,
                    region,
                    filter: &config.periodic_filter,
                    contrast_gain: stretch.gain,
                };
                pass.run(scores, image, cell_max)
            };
            let mut detection = detect(config.threshold, config.nms_radius, &mut scratch.cell_max);
            for (threshold, radius) in fallback_detections(config) {
                if detection.candidates.len() >= quota {
                    break;
                }
                let retry = detect(threshold, radius, &mut scratch.cell_max);
                if retry.candidates.len() > detection.candidates.len() {
                    detection = retry;
                }
            }
            report.low_contrast_rejected += detection.low_contrast_rejected;
            report.lattice_cells += detection.lattice_cells;
            report.excess_phase_rejected += detection.excess_phase_rejected;
            let candidates = detection.candidates;
            timings.decode_nms_ms += ms(t);

            let t = Instant::now();
            let selected = anms::select(
                config.anms,
                &candidates,
                quota,
                image.width(),
                image.height(),
            );
            timings.anms_ms += ms(t);

            let t = Instant::now();
            scratch.points.clear();
            scratch
                .points
                .extend(selected.iter().map(|&i| (candidates[i].x, candidates[i].y)));
            super::descriptors::sample_descriptors(
                desc,
                &scratch.points,
                &mut features.descriptors,
                &mut scratch.descriptor,
            );
            let size = PATCH_SIZE as f32 * scale;
            features.keypoints.extend(selected.iter().map(|&i| {
                let c = candidates[i];
                Keypoint {
                    x: c.x * scale,
                    y: c.y * scale,
                    size,
                    angle: patch.angle(image, c.x, c.y),
                    response: c.score,
                    octave: level as i32,
                }
            }));
            timings.descriptors_ms += ms(t);
        })
    }
}

/// One pyramid level and the exposure stretch measured on level 0.
struct LevelInput<'a> {
    level: usize,
    image: GrayImageView<'a>,
    stretch: ExposureStretch,
}

/// One detection on a level's score map: lattice suppression, NMS, border
/// removal and low-contrast rejection.
struct DetectionPass<'a> {
    threshold: f32,
    radius: usize,
    region: ValidRegion,
    filter: &'a PeriodicFilterConfig,
    /// The exposure stretch's gain: the contrast threshold is in the
    /// stretched image's gray levels.
    contrast_gain: f32,
}

/// The candidates of one [`DetectionPass`] and what the filter removed.
struct Detection {
    candidates: Vec<Candidate>,
    low_contrast_rejected: usize,
    excess_phase_rejected: usize,
    lattice_cells: usize,
}

impl DetectionPass<'_> {
    fn run(
        &self,
        scores: ArrayView2<'_, f32>,
        image: GrayImageView<'_>,
        cell_max: &mut Vec<(u8, f32)>,
    ) -> Detection {
        let filter = self.filter;
        let mask = if filter.enabled && filter.lattice_min_support > 0 {
            let (w, h) = (image.width(), image.height());
            LatticeMask::estimate(
                scores,
                w,
                h,
                self.threshold,
                filter.lattice_min_support,
                cell_max,
            )
        } else {
            LatticeMask::empty()
        };
        let adjust = |x: usize, y: usize, s: f32| if mask.is_suppressed(x, y) { 0.0 } else { s };
        let mut candidates =
            nms_candidates(scores, adjust, self.threshold, self.radius, self.region);
        let before = candidates.len();
        let contrast_filter = PeriodicFilterConfig {
            min_contrast: filter.min_contrast / self.contrast_gain,
            ..*filter
        };
        reject_low_contrast(&mut candidates, image, &contrast_filter);
        let low_contrast_rejected = before - candidates.len();
        let excess_phase_rejected = if filter.enabled {
            reject_excess_phases(&mut candidates, filter.max_phase_share)
        } else {
            0
        };
        Detection {
            low_contrast_rejected,
            excess_phase_rejected,
            lattice_cells: mask.suppressed_cells(),
            candidates,
        }
    }
}

/// The (threshold, NMS radius) pairs tried after the first detection on a
/// level that is short of its quota: `min_threshold`, a quarter and a
/// sixteenth of it, then that last threshold with half the NMS radius.
fn fallback_detections(config: &ExtractorConfig) -> impl Iterator<Item = (f32, usize)> {
    let (first, min, r) = (config.threshold, config.min_threshold, config.nms_radius);
    let half_radius = (r / 2).max(1).min(r);
    [
        (min, r),
        (min / 4.0, r),
        (min / 16.0, r),
        (min / 16.0, half_radius),
    ]
    .into_iter()
    .filter(move |&(t, radius)| t < first || radius < r)
}

fn ms(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}
