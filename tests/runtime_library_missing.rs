//! A missing ONNX Runtime library is a clear error (this file is its own
//! process, so no earlier test has loaded the library).

use std::path::PathBuf;

use spslam::features::{ExtractorConfig, FeatureError, SuperPointExtractor};

#[test]
fn a_missing_runtime_library_is_a_clear_error_not_a_panic() {
    let model = spslam::features::default_model_path();
    // Any existing file stands in for the model: the library is loaded first.
    let model_path = if model.is_file() {
        model
    } else {
        PathBuf::from(file!()).canonicalize().unwrap()
    };
    let config = ExtractorConfig {
        model_path: Some(model_path),
        ort_library_path: Some(PathBuf::from("/nonexistent/libonnxruntime.so.1.31.1")),
        ..Default::default()
    };
    match SuperPointExtractor::new(config) {
        Err(e @ FeatureError::RuntimeLibrary { .. }) => {
            let text = e.to_string();
            assert!(
                text.contains("/nonexistent/libonnxruntime.so.1.31.1"),
                "{text}"
            );
            assert!(text.contains("make setup"), "{text}");
        }
        other => panic!("expected RuntimeLibrary, got {other:?}"),
    }
}
