//! Real maps for the map-storage tests: stereo SLAM over a synthetic
//! street, with ORB (binary descriptors, no model needed) or SuperPoint
//! (float descriptors), local mapping inline (deterministic).

use spslam::dataset::synthetic::SceneName;
use spslam::settings::ExtractorSettings;
use spslam::system::SlamSystem;
use spslam::tracking::Frontend;

use super::synthetic_slam::{cached_images, orb_slam, rig_of, small_sequence};

/// ORB stereo SLAM over `frames` frames of the loop scene, finished.
pub fn orb_system(frames: usize) -> SlamSystem {
    let sequence = small_sequence(SceneName::Loop, frames);
    let mut slam = orb_slam(&sequence);
    run(&mut slam, &sequence);
    slam
}

/// SuperPoint (int8, one level, `features` keypoints) stereo SLAM over
/// `frames` frames of the loop scene, finished.
pub fn superpoint_system(frames: usize, features: usize) -> SlamSystem {
    let sequence = small_sequence(SceneName::Loop, frames);
    let rig = rig_of(&sequence);
    let settings = ExtractorSettings {
        n_features: features,
        ..ExtractorSettings::default()
    };
    let config = settings.superpoint_config(1, 1);
    let sp = || Box::new(super::cached_extractor(config.clone()));
    let mut slam = SlamSystem::new(rig, Frontend::new(sp(), sp(), &rig));
    run(&mut slam, &sequence);
    slam
}

fn run(slam: &mut SlamSystem, sequence: &spslam::dataset::synthetic::SyntheticSequence) {
    for i in 0..sequence.len() {
        let (t, l, r) = cached_images(sequence, i);
        slam.process(i, t, l.view(), r.view())
            .unwrap_or_else(|e| panic!("frame {i}: {e}"));
    }
    slam.finish().unwrap_or_else(|e| panic!("{e}"));
}
