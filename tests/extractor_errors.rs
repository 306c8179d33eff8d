//! Bad input ends in a typed error that names what is wrong, never a panic.

mod common;

use std::path::PathBuf;

use spslam::features::{
    Device, ExtractorConfig, FeatureError, GrayImage, GrayImageView, PeriodicFilterConfig,
    SuperPointExtractor,
};

#[test]
fn image_views_reject_bad_geometry() {
    let buf = vec![0u8; 100];
    assert!(matches!(
        GrayImageView::new(&buf, 0, 10, 10),
        Err(FeatureError::EmptyImage { .. })
    ));
    assert!(matches!(
        GrayImageView::new(&buf, 10, 0, 10),
        Err(FeatureError::EmptyImage { .. })
    ));
    assert!(matches!(
        GrayImageView::new(&buf, 10, 10, 9),
        Err(FeatureError::StrideTooSmall {
            stride: 9,
            width: 10
        })
    ));
    assert!(matches!(
        GrayImageView::new(&buf, 10, 11, 10),
        Err(FeatureError::BufferTooSmall {
            required: 110,
            actual: 100,
            ..
        })
    ));
    assert!(matches!(
        GrayImageView::new(&buf, 1 << 20, 1, 1 << 20),
        Err(FeatureError::ImageTooLarge { .. })
    ));
    // The last row needs only `width` bytes, not a full stride.
    assert!(GrayImageView::new(&buf, 10, 10, 10).is_ok());
    assert!(GrayImageView::new(&buf[..95], 5, 10, 10).is_ok());
}

#[test]
fn configs_out_of_range_are_named() {
    let cases: Vec<(ExtractorConfig, &str)> = vec![
        (
            ExtractorConfig {
                n_features: 0,
                ..Default::default()
            },
            "n_features",
        ),
        (
            ExtractorConfig {
                scale_factor: 1.0,
                ..Default::default()
            },
            "scale_factor",
        ),
        (
            ExtractorConfig {
                scale_factor: f32::NAN,
                ..Default::default()
            },
            "scale_factor",
        ),
        (
            ExtractorConfig {
                n_levels: 0,
                ..Default::default()
            },
            "n_levels",
        ),
        (
            ExtractorConfig {
                threshold: 0.0,
                ..Default::default()
            },
            "threshold",
        ),
        (
            ExtractorConfig {
                threshold: 0.001,
                min_threshold: 0.002,
                ..Default::default()
            },
            "min_threshold",
        ),
        (
            ExtractorConfig {
                nms_radius: 1000,
                ..Default::default()
            },
            "nms_radius",
        ),
        (
            ExtractorConfig {
                periodic_filter: PeriodicFilterConfig {
                    lattice_min_support: 5,
                    ..Default::default()
                },
                ..Default::default()
            },
            "periodic_filter.lattice_min_support",
        ),
        (
            ExtractorConfig {
                periodic_filter: PeriodicFilterConfig {
                    min_contrast: -1.0,
                    ..Default::default()
                },
                ..Default::default()
            },
            "periodic_filter.min_contrast",
        ),
    ];
    for (config, field) in cases {
        match SuperPointExtractor::new(config) {
            Err(FeatureError::InvalidConfig { name, .. }) => assert_eq!(name, field),
            other => panic!("{field}: expected InvalidConfig, got {other:?}"),
        }
    }
}

#[test]
fn a_missing_model_is_named() {
    let config = ExtractorConfig {
        model_path: Some(PathBuf::from("/nonexistent/superpoint.onnx")),
        ..Default::default()
    };
    match SuperPointExtractor::new(config) {
        Err(e @ FeatureError::ModelNotFound { .. }) => {
            assert!(e.to_string().contains("/nonexistent/superpoint.onnx"))
        }
        other => panic!("expected ModelNotFound, got {other:?}"),
    }
}

#[test]
fn a_malformed_model_is_an_interface_error() {
    if !common::model_available("a_malformed_model_is_an_interface_error") {
        return;
    }
    let dir = std::env::temp_dir().join(format!("spslam-bad-model-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("garbage.onnx");
    std::fs::write(&path, b"this is not an ONNX protobuf").unwrap();
    let result = SuperPointExtractor::new(ExtractorConfig {
        model_path: Some(path.clone()),
        ..Default::default()
    });
    std::fs::remove_dir_all(&dir).ok();
    match result {
        Err(e @ FeatureError::ModelInterface { .. }) => println!("{e}"),
        other => panic!("expected ModelInterface, got {other:?}"),
    }
}

#[test]
fn tiny_and_unreadable_images_are_errors() {
    let missing = GrayImage::load(std::path::Path::new("/nonexistent/frame.png"));
    assert!(matches!(missing, Err(FeatureError::ImageRead { .. })));
    let dir = std::env::temp_dir().join(format!("spslam-bad-image-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let junk = dir.join("junk.png");
    std::fs::write(&junk, b"\x89PNG but not really").unwrap();
    let result = GrayImage::load(&junk);
    std::fs::remove_dir_all(&dir).ok();
    assert!(
        matches!(result, Err(FeatureError::ImageRead { .. })),
        "{result:?}"
    );

    if !common::model_available("tiny_and_unreadable_images_are_errors") {
        return;
    }
    let mut ex = common::extractor(ExtractorConfig::default());
    let tiny = vec![128u8; 8 * 8];
    let view = GrayImageView::new(&tiny, 8, 8, 8).unwrap();
    assert!(matches!(
        ex.extract(view),
        Err(FeatureError::ImageTooSmall { .. })
    ));
    // A flat image is valid input and gives no keypoints, not an error.
    let flat = vec![90u8; 64 * 48];
    let f = ex
        .extract(GrayImageView::new(&flat, 64, 48, 64).unwrap())
        .unwrap();
    assert!(f.is_empty());
}

#[test]
fn cuda_without_a_cuda_runtime_is_a_clear_error_and_auto_falls_back_to_the_cpu() {
    if !common::model_available("cuda_without_a_cuda_runtime_is_a_clear_error") {
        return;
    }
    let config = |device| ExtractorConfig {
        device,
        ..Default::default()
    };
    match SuperPointExtractor::new(config(Device::Cuda)) {
        Ok(extractor) => {
            // Only possible with a CUDA build of ONNX Runtime on a GPU machine.
            assert!(spslam::features::model::cuda_offered());
            assert_eq!(extractor.device(), Device::Cuda);
        }
        Err(e @ FeatureError::DeviceUnavailable { .. }) => {
            let text = e.to_string();
            assert!(text.contains("make setup-gpu"), "{text}");
            assert!(text.contains("--device cpu"), "{text}");
            if !spslam::features::model::cuda_offered() {
                assert!(text.contains("CPU build"), "{text}");
            }
        }
        Err(other) => panic!("expected DeviceUnavailable, got {other:?}"),
    }
    let auto = SuperPointExtractor::new(config(Device::Auto)).expect("auto must always work");
    if !spslam::features::model::cuda_offered() {
        assert_eq!(auto.device(), Device::Cpu);
    }
    let cpu = SuperPointExtractor::new(config(Device::Cpu)).expect("cpu must always work");
    assert_eq!(cpu.device(), Device::Cpu);
}
