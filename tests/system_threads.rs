//! The system's worker threads fail as the caller can act on: a panicking
//! loop-closing thread surfaces as an error naming that thread with the
//! panic's message, and a failing global BA is reported in the run's
//! global-BA log and skipped, with every frame's row kept (synthetic
//! 480×360 street; ORB, and SuperPoint int8 where loop closing needs
//! float descriptors).

mod common;

use std::sync::Arc;

use common::synthetic_slam::{images, orb_slam, rig_of, small_sequence};
use spslam::dataset::synthetic::SceneName;
use spslam::error::SlamError;
use spslam::loop_closing::LoopThresholds;
use spslam::place::{GlobalDescriptor, PlaceError};
use spslam::settings::ExtractorSettings;
use spslam::system::SlamSystem;
use spslam::tracking::{Frontend, TrackingState};

fn ok<T, E: std::fmt::Display>(r: Result<T, E>) -> T {
    r.unwrap_or_else(|e| panic!("{e}"))
}

/// A run of `frames` frames that asks for a global BA at frame 10 with a
/// planted panic, and at frame 20 without it.
fn run_with_failing_global_ba(threaded: bool, frames: usize) -> SlamSystem {
    let sequence = small_sequence(SceneName::Straight, frames);
    let mut slam = orb_slam(&sequence);
    if threaded {
        ok(slam.spawn_mapping_thread());
    }
    for i in 0..frames {
        if i == 10 {
            slam.set_before_global_ba(Some(Arc::new(|| panic!("planted panic in the global BA"))));
            ok(slam.request_global_ba());
        }
        if i == 20 {
            slam.set_before_global_ba(None);
            ok(slam.request_global_ba());
        }
        let (t, l, r) = images(&sequence, i);
        ok(slam.process(i, t, l.view(), r.view()));
    }
    ok(slam.finish());
    slam
}

#[test]
fn a_failing_global_ba_is_reported_and_skipped_and_every_frame_keeps_its_row() {
    for threaded in [false, true] {
        let frames = 30;
        let slam = run_with_failing_global_ba(threaded, frames);
        let records = slam.records();
        assert_eq!(records.len(), frames, "threaded {threaded}");
        let lost = common::untracked(records);
        assert!(lost.is_empty(), "threaded {threaded}: lost frames {lost:?}");
        let runs = slam.global_ba_runs();
        eprintln!("threaded {threaded}: global BA runs {runs:?}");
        assert_eq!(runs.len(), 2, "threaded {threaded}");
        let failure = runs[0].failure.as_deref().unwrap_or_default();
        assert!(
            failure.contains("global-ba") && failure.contains("planted panic in the global BA"),
            "threaded {threaded}: {failure:?}"
        );
        assert_eq!(runs[1].failure, None, "threaded {threaded}");
        assert!(runs[1].keyframes >= 2, "threaded {threaded}: {:?}", runs[1]);
    }
}

/// A place-recognition descriptor that panics when asked for anything.
struct PanickingDescriptor;

impl GlobalDescriptor for PanickingDescriptor {
    fn local_dim(&self) -> usize {
        256
    }

    fn dim(&self) -> usize {
        8
    }

    fn compute_flat(&self, _: &[f32]) -> Result<Vec<f32>, PlaceError> {
        panic!("planted panic in loop detection")
    }
}

#[test]
fn a_panicking_loop_closing_thread_surfaces_with_its_name_and_message() {
    if !common::model_available("a_panicking_loop_closing_thread_surfaces") {
        return;
    }
    let frames = 30;
    let sequence = small_sequence(SceneName::Straight, frames);
    let rig = rig_of(&sequence);
    let config = ExtractorSettings::default().superpoint_config(1, 1);
    let sp = || Box::new(common::extractor(config.clone()));
    let mut slam = SlamSystem::new(rig, Frontend::new(sp(), sp(), &rig));
    ok(slam.spawn_mapping_thread());
    ok(slam.enable_loop_closing(Arc::new(PanickingDescriptor), LoopThresholds::default()));
    let mut error = None;
    for i in 0..frames {
        let (t, l, r) = images(&sequence, i);
        match slam.process(i, t, l.view(), r.view()) {
            Ok(record) => assert_ne!(record.state, TrackingState::Lost, "frame {i}"),
            Err(e) => {
                eprintln!("frame {i}: {e}");
                error = Some(e);
                break;
            }
        }
    }
    let error = match error {
        Some(e) => e,
        None => match slam.finish() {
            Err(e) => e,
            Ok(()) => panic!("the loop-closing thread's panic was never reported"),
        },
    };
    assert!(
        matches!(&error, SlamError::Thread { name: "loop-closing", reason }
            if reason.contains("planted panic in loop detection")),
        "{error}"
    );
    assert!(
        error
            .to_string()
            .contains("the loop-closing thread stopped"),
        "{error}"
    );
}
