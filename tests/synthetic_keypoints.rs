//! SuperPoint finds plenty of keypoints on every synthetic scene: at least
//! 300 per 640×480 frame with the default config (1000 features).

mod common;

use spslam::dataset::synthetic::{SceneName, SyntheticConfig, SyntheticSequence};
use spslam::features::{ExtractorConfig, GrayImage};

/// Frames checked per scene: the start, and two well inside the sequence.
const FRAMES: [(SceneName, [usize; 3]); 3] = [
    (SceneName::Loop, [0, 60, 140]),
    (SceneName::Straight, [0, 80, 160]),
    (SceneName::Wobbly, [0, 90, 180]),
];
const MIN_KEYPOINTS: usize = 300;

#[test]
fn superpoint_finds_at_least_300_keypoints_in_every_scene() {
    if !common::model_available("superpoint_finds_at_least_300_keypoints_in_every_scene") {
        return;
    }
    let mut extractor = common::extractor(ExtractorConfig::default());
    let mut failures = Vec::new();
    for (scene, frames) in FRAMES {
        let sequence = SyntheticSequence::new(SyntheticConfig::for_scene(scene)).unwrap();
        for index in frames {
            let frame = sequence.render(index, false);
            let image = GrayImage::from_vec(frame.left, frame.width, frame.height).unwrap();
            let count = extractor
                .extract(image.view())
                .unwrap_or_else(|e| panic!("{e}"))
                .keypoints
                .len();
            println!("{scene} frame {index}: {count} keypoints");
            if count < MIN_KEYPOINTS {
                failures.push(format!("{scene} frame {index}: {count}"));
            }
        }
    }
    assert!(
        failures.is_empty(),
        "fewer than {MIN_KEYPOINTS} keypoints: {failures:?}"
    );
}
