//! The training descriptors: the extractor `spslam vocab train` is asked
//! for, run over every training image.

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use spslam::features::sign_bits::pack_sign_bits;
use spslam::features::{
    threads_per_extractor, DescriptorSet, ExtractorConfig, FeatureExtractor, GrayImage, OrbConfig,
    OrbExtractor, Precision, SuperPointExtractor,
};
use spslam::place::DescriptorRows;
use spslam::settings::{ExtractorSettings, SlamSettings, DEFAULT_SUPERPOINT_LEVELS};

use super::{DescriptorChoice, TrainArgs};

/// Keypoints per image without `--settings` or `--features` (as `spslam extract`).
const DEFAULT_FEATURES: usize = 1000;

/// Every training image's descriptors, one image after the other.
pub enum TrainingRows {
    /// SuperPoint's float rows.
    Float(DescriptorRows<f32>),
    /// Binary rows: sign bits or ORB.
    Binary(DescriptorRows<u8>),
}

/// The descriptors and how many each image gave.
pub struct TrainingSet {
    /// The rows.
    pub rows: TrainingRows,
    /// Rows per image, in image order.
    pub image_lengths: Vec<usize>,
    /// The extractor, for the summary (e.g. `superpoint+anms-kdtree, fp32 on cpu, 1 levels`).
    pub extractor: String,
}

impl TrainingSet {
    /// Number of descriptors.
    pub fn len(&self) -> usize {
        match &self.rows {
            TrainingRows::Float(rows) => rows.len(),
            TrainingRows::Binary(rows) => rows.len(),
        }
    }
}

/// The extractor the arguments describe. With `--settings`, the
/// configuration the C++ shim builds for ORB-SLAM3 from the same file.
pub fn extractor(args: &TrainArgs) -> Result<Box<dyn FeatureExtractor>> {
    let settings = match &args.settings {
        Some(path) => Some(SlamSettings::from_file(path)?),
        None => None,
    };
    let e = settings.as_ref().map(|s| &s.extractor);
    if args.descriptors == DescriptorChoice::Orb {
        let config = match e {
            Some(e) => OrbConfig {
                n_features: e.n_features,
                scale_factor: e.scale_factor as f32,
                n_levels: e.n_levels,
                ini_th_fast: e.ini_th_fast,
                min_th_fast: e.min_th_fast,
            },
            None => OrbConfig {
                n_features: args.features.unwrap_or(DEFAULT_FEATURES),
                n_levels: args.pyramid_levels.unwrap_or(OrbConfig::default().n_levels),
                ..OrbConfig::default()
            },
        };
        return Ok(Box::new(
            OrbExtractor::new(config).context("cannot create the ORB extractor")?,
        ));
    }
    let mut config = match e {
        // As the shim: spslam_config_from_orb_slam3 with ORBextractor.*, fp32 unless told.
        Some(e) => {
            let mut config = ExtractorConfig::from_orb_slam3(
                i32::try_from(e.n_features)?,
                e.scale_factor as f32,
                i32::try_from(e.n_levels)?,
                e.ini_th_fast,
                e.min_th_fast,
            );
            config.precision = args.precision.unwrap_or(Precision::Fp32);
            // One image at a time here, not ORB-SLAM3's stereo pair at once.
            config.threads = threads_per_extractor(1);
            config
        }
        // As `spslam extract` with its defaults.
        None => ExtractorConfig {
            n_features: args.features.unwrap_or(DEFAULT_FEATURES),
            n_levels: args.pyramid_levels.unwrap_or(DEFAULT_SUPERPOINT_LEVELS),
            precision: args.precision.unwrap_or_default(),
            ..ExtractorConfig::default()
        },
    };
    config.device = args.device;
    if let Some(model) = &args.model {
        config.model_path = Some(model.clone());
    }
    Ok(Box::new(
        SuperPointExtractor::new(config).context("cannot create the SuperPoint extractor")?,
    ))
}

/// The SuperPoint configuration of `spslam run` for the arguments (for
/// `--format vlad`): with `--settings`, that file's extractor as `spslam run`
/// reads it (`SuperPoint.nLevels`, `SuperPoint.precision`, ...); without,
/// `spslam run`'s defaults ([`ExtractorSettings::default`] on
/// [`DEFAULT_SUPERPOINT_LEVELS`] levels, the stereo and RGB-D default), with `--features`,
/// `--pyramid-levels`, `--precision` and `--device` applied.
pub fn run_superpoint_config(args: &TrainArgs) -> Result<ExtractorConfig> {
    let mut e = match &args.settings {
        Some(path) => SlamSettings::from_file(path)?.extractor,
        None => ExtractorSettings::default(),
    };
    if let Some(n) = args.features {
        e.n_features = n;
    }
    if let Some(p) = args.precision {
        e.precision = p;
    }
    if let Some(model) = &args.model {
        e.model = Some(model.clone());
    }
    e.device = args.device;
    let levels = args
        .pyramid_levels
        .unwrap_or(e.superpoint_levels_for(false));
    Ok(e.superpoint_config(levels, threads_per_extractor(1)))
}

/// Runs `extractor` over `paths`, with a progress bar, keeping the rows
/// `choice` asks for.
pub fn extract_all(
    extractor: &mut dyn FeatureExtractor,
    choice: DescriptorChoice,
    paths: &[PathBuf],
) -> Result<TrainingSet> {
    let bar = ProgressBar::new(paths.len() as u64);
    bar.set_style(
        ProgressStyle::with_template(
            "extracting {bar:40} {pos}/{len} images, {elapsed} ({eta} left) {msg}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let mut float: Option<DescriptorRows<f32>> = None;
    let mut binary: Option<DescriptorRows<u8>> = None;
    let mut image_lengths = Vec::with_capacity(paths.len());
    for path in paths {
        let image = GrayImage::load(path)
            .with_context(|| format!("cannot read training image {}", path.display()))?;
        let features = extractor
            .extract(image.view())
            .with_context(|| format!("extraction failed on {}", path.display()))?;
        image_lengths.push(features.descriptors.len());
        match (choice, &features.descriptors) {
            (DescriptorChoice::Float, DescriptorSet::Float { dim, data }) => {
                append(&mut float, *dim, data, path)?;
            }
            (DescriptorChoice::Binary, DescriptorSet::Float { dim, data }) => {
                let mut packed = Vec::with_capacity(data.len() / 8 + 1);
                pack_sign_bits(data, *dim, &mut packed);
                append(&mut binary, dim.div_ceil(8), &packed, path)?;
            }
            (DescriptorChoice::Orb, DescriptorSet::Binary { data }) => {
                append(&mut binary, 32, data.as_flattened(), path)?;
            }
            (_, other) => bail!(
                "the extractor gave {} descriptors for --descriptors {choice:?}",
                other.kind()
            ),
        }
        bar.set_message(format!(
            "{} descriptors",
            image_lengths.iter().sum::<usize>()
        ));
        bar.inc(1);
    }
    bar.finish();
    let rows = match (float, binary) {
        (Some(rows), _) => TrainingRows::Float(rows),
        (None, Some(rows)) => TrainingRows::Binary(rows),
        (None, None) => bail!(
            "the {} training images gave no keypoints; nothing to train on",
            paths.len()
        ),
    };
    Ok(TrainingSet {
        rows,
        image_lengths,
        extractor: format!("{} ({})", extractor.name(), extractor.inference_summary()),
    })
}

/// Appends one image's rows, all images' rows being `row_len` long.
fn append<T: Copy>(
    rows: &mut Option<DescriptorRows<T>>,
    row_len: usize,
    values: &[T],
    path: &std::path::Path,
) -> Result<()> {
    if values.is_empty() {
        return Ok(());
    }
    if rows.is_none() {
        *rows = Some(DescriptorRows::new(row_len)?);
    }
    let Some(rows) = rows.as_mut() else {
        return Ok(());
    };
    if rows.row_len() != row_len {
        bail!(
            "{} gave {row_len}-value descriptors, earlier images {}",
            path.display(),
            rows.row_len()
        );
    }
    rows.extend_from_flat(values)?;
    Ok(())
}
