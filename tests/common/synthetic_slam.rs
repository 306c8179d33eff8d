//! Stereo SLAM with ORB on synthetic sequences rendered in memory at
//! 480×360 (focal 0.75× the default): one place to build the sequence, the
//! rig and the system, shared by the SLAM integration tests.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};

use spslam::camera::CameraRig;
use spslam::dataset::synthetic::{
    Condition, SceneName, SyntheticConfig, SyntheticFrame, SyntheticSequence,
};
use spslam::features::{GrayImage, OrbConfig, OrbExtractor};
use spslam::settings::SlamSettings;
use spslam::system::SlamSystem;
use spslam::tracking::Frontend;

/// `frames` frames of `scene` at the tests' 480×360 size.
pub fn small_sequence(scene: SceneName, frames: usize) -> SyntheticSequence {
    small_sequence_of(scene, Some(frames))
}

/// The scene's own frame count (one lap of the loop) at the tests' size.
pub fn small_lap(scene: SceneName) -> SyntheticSequence {
    small_sequence_of(scene, None)
}

fn small_sequence_of(scene: SceneName, frames: Option<usize>) -> SyntheticSequence {
    let mut config = SyntheticConfig::for_scene(scene);
    config.frames = frames;
    config.width = 480;
    config.height = 360;
    config.focal_length *= 0.75;
    SyntheticSequence::new(config).unwrap_or_else(|e| panic!("{e}"))
}

/// The sequence's rig with default settings.
pub fn rig_of(sequence: &SyntheticSequence) -> CameraRig {
    let cam = *sequence.camera();
    let settings = SlamSettings::rectified_stereo(cam.fx, cam.fy, cam.cx, cam.cy, cam.baseline);
    CameraRig::from_settings(&settings, cam.width, cam.height).unwrap_or_else(|e| panic!("{e}"))
}

/// An ORB stereo SLAM system for the sequence, mapping inline, with the
/// map's invariants checked after every local-mapping step.
pub fn orb_slam(sequence: &SyntheticSequence) -> SlamSystem {
    let rig = rig_of(sequence);
    let orb =
        || Box::new(OrbExtractor::new(OrbConfig::default()).unwrap_or_else(|e| panic!("{e}")));
    let mut slam = SlamSystem::new(rig, Frontend::new(orb(), orb(), &rig));
    if let Some(mapper) = slam.mapper_mut() {
        mapper.check_invariants = true;
    }
    slam
}

/// Frame `index` of the sequence as a left and right image.
pub fn images(sequence: &SyntheticSequence, index: usize) -> (f64, GrayImage, GrayImage) {
    let frame = sequence.render(index, false);
    let image = |data: Vec<u8>| {
        GrayImage::from_vec(data, frame.width, frame.height).unwrap_or_else(|e| panic!("{e}"))
    };
    (frame.timestamp, image(frame.left), image(frame.right))
}

/// The part of `sequence`'s configuration a frame's pixels depend on: on
/// the loop in its own light (no condition) the frame count only ends the
/// sequence, so runs of 232 and of 500 frames share their frames
/// (`tests/synthetic_sequence.rs` checks that the pixels agree). The open
/// scenes build a street as long as the run, and conditions place their
/// changes by the frame count: the count stays in their key.
pub fn pixel_config(sequence: &SyntheticSequence) -> SyntheticConfig {
    let mut config = sequence.config().clone();
    if config.scene == SceneName::Loop && config.condition == Condition::Normal {
        config.frames = None;
    }
    config
}

/// `sequence.render(index, with_depth)`, read back from the disk cache
/// when another test of the run rendered it ([`super::disk_cache`];
/// rendering is deterministic: the same configuration and index give the
/// same pixels).
pub fn rendered(sequence: &SyntheticSequence, index: usize, with_depth: bool) -> SyntheticFrame {
    use super::disk_cache::{self, Reader, Writer};
    use std::hash::Hash;
    const KIND: &str = "frame";
    let key = disk_cache::key(|h| {
        format!("{:?}", pixel_config(sequence)).hash(h);
        (index, with_depth).hash(h);
    });
    let decode = |bytes: &[u8]| {
        let mut r = Reader(bytes);
        let frame = SyntheticFrame {
            index,
            timestamp: r.f64()?,
            pose: sequence.pose(index),
            width: usize::try_from(r.u64()?).ok()?,
            height: usize::try_from(r.u64()?).ok()?,
            left: r.bytes()?,
            right: r.bytes()?,
            depth: r.f32s()?,
        };
        r.is_done().then_some(frame)
    };
    let encode = |frame: &SyntheticFrame| {
        let mut w = Writer::default();
        w.f64(frame.timestamp);
        w.u64(frame.width as u64);
        w.u64(frame.height as u64);
        w.bytes(&frame.left);
        w.bytes(&frame.right);
        w.f32s(&frame.depth);
        w.0
    };
    let Ok(frame) = disk_cache::get_or_compute(KIND, key, decode, encode, || {
        Ok::<_, std::convert::Infallible>(sequence.render(index, with_depth))
    });
    frame
}

/// [`images`] through a process-wide cache and the run's disk cache
/// ([`rendered`]), for runs with local mapping inline that see frames other
/// runs of the test suite see too (rendering a 480×360 stereo frame takes
/// about 90 ms). Keyed by the sequence's whole configuration and the index.
/// Not for runs with a mapping thread: a frame read back costs no time,
/// which would change how far the thread falls behind.
pub fn cached_images(sequence: &SyntheticSequence, index: usize) -> (f64, GrayImage, GrayImage) {
    type Frames = Mutex<HashMap<(String, usize), Arc<(f64, GrayImage, GrayImage)>>>;
    static FRAMES: OnceLock<Frames> = OnceLock::new();
    let frames = FRAMES.get_or_init(Frames::default);
    let key = (format!("{:?}", pixel_config(sequence)), index);
    let cached = frames.lock().ok().and_then(|f| f.get(&key).cloned());
    let frame = match cached {
        Some(frame) => frame,
        None => {
            let frame = rendered(sequence, index, false);
            let image = |data: Vec<u8>| {
                GrayImage::from_vec(data, frame.width, frame.height)
                    .unwrap_or_else(|e| panic!("{e}"))
            };
            let frame = Arc::new((frame.timestamp, image(frame.left), image(frame.right)));
            if let Ok(mut f) = frames.lock() {
                f.insert(key, frame.clone());
            }
            frame
        }
    };
    frame.as_ref().clone()
}

/// Runs `slam` over every frame of the sequence (rendered, stereo), finishes
/// it and evaluates its trajectory against the sequence's ground truth
/// (paired by index, the first pose at the origin).
pub fn run_against_truth(
    slam: &mut SlamSystem,
    sequence: &SyntheticSequence,
) -> spslam::eval::EvalReport {
    use spslam::eval::{evaluate, EvalOptions, Pairing, Trajectory};
    let ok = |r: Result<(), spslam::error::SlamError>| r.unwrap_or_else(|e| panic!("{e}"));
    let first = sequence.pose(0).inverse();
    let mut truth = Vec::new();
    for i in 0..sequence.len() {
        let (t, left, right) = images(sequence, i);
        ok(slam.process(i, t, left.view(), right.view()).map(|_| ()));
        truth.push((t, first * sequence.pose(i)));
    }
    ok(slam.finish());
    let poses = slam.trajectory().unwrap_or_else(|e| panic!("{e}"));
    let estimate = Trajectory::new(
        poses.iter().map(|(t, _)| *t).collect(),
        poses.iter().map(|(_, p)| p.to_isometry()).collect(),
    );
    let reference = Trajectory::new(
        truth.iter().map(|(t, _)| *t).collect(),
        truth.iter().map(|(_, p)| *p).collect(),
    );
    let options = EvalOptions {
        pairing: Pairing::ByIndex,
        ..EvalOptions::default()
    };
    evaluate(&reference, &estimate, &options).unwrap_or_else(|e| panic!("{e}"))
}

/// What a SuperPoint stereo run on a synthetic sequence gave.
pub struct SuperPointRun {
    /// Frames not tracked.
    pub lost: Vec<usize>,
    /// Maps in the atlas at the end.
    pub maps: usize,
    /// The trajectory against the sequence's ground truth.
    pub report: spslam::eval::EvalReport,
}

/// SuperPoint + ANMS (the settings' extractor on one level, one thread per
/// image) in stereo over every frame of `sequence`, local mapping inline,
/// with the rectified-stereo settings of its camera edited by `configure`.
pub fn superpoint_stereo_run(
    sequence: &SyntheticSequence,
    configure: impl FnOnce(&mut SlamSettings),
) -> SuperPointRun {
    let cam = *sequence.camera();
    let mut settings = SlamSettings::rectified_stereo(cam.fx, cam.fy, cam.cx, cam.cy, cam.baseline);
    configure(&mut settings);
    let rig = CameraRig::from_settings(&settings, cam.width, cam.height)
        .unwrap_or_else(|e| panic!("{e}"));
    let sp_config = settings.extractor.superpoint_config(1, 1);
    let sp = || Box::new(super::extractor(sp_config.clone()));
    let mut slam = SlamSystem::new(rig, Frontend::new(sp(), sp(), &rig));
    let report = run_against_truth(&mut slam, sequence);
    let summary = slam.summary().unwrap_or_else(|e| panic!("{e}"));
    SuperPointRun {
        lost: super::untracked(slam.records()),
        maps: summary.maps.len(),
        report,
    }
}
