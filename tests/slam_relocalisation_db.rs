//! Relocalisation from the loop-closing keyframe database (ORB-SLAM3's
//! `DetectRelocalizationCandidates`) rather than a scan of the 30 newest
//! keyframes, on the synthetic city block with exact ground truth,
//! SuperPoint + ANMS on one level (int8), 480×360, local mapping inline
//! (deterministic), the default codebook `models/vlad_k64.spvlad`:
//!
//! the camera drives half a lap, the images go black for a few frames
//! (tracking is lost), and the camera comes back at the start of the lap,
//! a place last seen far more than 30 keyframes earlier. With loop closing
//! on, the database finds the start's keyframes and the first real frame
//! (or one of the next two, before the tracker gives the map up) is
//! relocalised within 0.3 m of the truth, in the first map. The same run
//! with loop closing off (the scan) is printed, not asserted.
//!
//! Every measured value is printed (`--nocapture`).

mod common;

use common::synthetic_slam::{cached_images, rig_of, small_sequence};
use spslam::dataset::synthetic::{SceneName, SyntheticSequence};
use spslam::features::GrayImage;
use spslam::settings::ExtractorSettings;
use spslam::system::SlamSystem;
use spslam::tracking::{Frontend, TrackingMethod, TrackingState, MAX_SCANNED_KEYFRAMES};

/// Frames of the lap driven before the blackout (about half the lap of
/// 231 frames: the camera is on the far side of the block, looking away
/// from the start).
const DRIVEN: usize = 120;
/// Black frames: tracking is lost on the first one. With a patience of 5
/// frames (0.5 s at 10 fps) the tracker starts a new map on the 5th frame
/// after the loss, so 2 black frames leave 3 real frames to relocalise.
const BLACK: usize = 2;
/// The first frame of the lap the camera comes back at.
const REVISIT_FROM: usize = 5;
/// Frames of the revisit fed after the blackout.
const REVISIT: usize = 20;
/// The relocalisation must happen within this many real frames.
const WITHIN: usize = 3;
/// Largest position error of the relocalised frame (metres).
const MAX_ERROR_M: f64 = 0.3;

fn ok<T, E: std::fmt::Display>(r: Result<T, E>) -> T {
    r.unwrap_or_else(|e| panic!("{e}"))
}

/// One input frame: the sequence frame it shows (`None`: black).
#[derive(Clone, Copy)]
struct Input {
    shows: Option<usize>,
    timestamp: f64,
}

/// The inputs: the lap's start, black frames, the start again, with
/// increasing timestamps at the sequence's frame rate.
fn inputs(sequence: &SyntheticSequence) -> Vec<Input> {
    let dt = sequence.timestamp(1) - sequence.timestamp(0);
    let mut out: Vec<Input> = (0..DRIVEN)
        .map(|i| Input {
            shows: Some(i),
            timestamp: sequence.timestamp(i),
        })
        .collect();
    let shows = std::iter::repeat_n(None, BLACK)
        .chain((REVISIT_FROM..REVISIT_FROM + REVISIT).map(Some))
        .collect::<Vec<_>>();
    for shows in shows {
        let last = out.last().map_or(0.0, |i| i.timestamp);
        out.push(Input {
            shows,
            timestamp: last + dt,
        });
    }
    out
}

/// What one run gave.
struct Run {
    /// Input index of the first relocalised frame after the blackout.
    relocalised: Option<usize>,
    /// Its position error (m) and inliers.
    error_m: f64,
    inliers: usize,
    /// Per revisit input: (input, shows, state, method, map, error m).
    revisit: Vec<(usize, usize, TrackingState, TrackingMethod, usize, f64)>,
    /// Frames of the first map's live keyframes made before the blackout
    /// (at the end of the run: culling only removes, so as many or more
    /// were live at the loss).
    keyframes_before: Vec<usize>,
    /// Maps in the atlas at the end.
    maps: usize,
    database: bool,
}

fn run(sequence: &SyntheticSequence, loop_closing: bool) -> Run {
    let rig = rig_of(sequence);
    let config = ExtractorSettings::default().superpoint_config(1, 1);
    // Both runs show the same images: each is extracted once.
    let sp = || Box::new(common::cached_extractor(config.clone()));
    let mut slam = SlamSystem::new(rig, Frontend::new(sp(), sp(), &rig));
    if loop_closing {
        common::enable_loop_closing(&mut slam, &config);
    }
    let camera = sequence.camera();
    let black = || {
        ok(GrayImage::from_vec(
            vec![0; camera.width * camera.height],
            camera.width,
            camera.height,
        ))
    };
    let inputs = inputs(sequence);
    for (index, input) in inputs.iter().enumerate() {
        let (left, right) = match input.shows {
            Some(i) => {
                let (_, l, r) = cached_images(sequence, i);
                (l, r)
            }
            None => (black(), black()),
        };
        ok(slam.process(index, input.timestamp, left.view(), right.view()));
    }
    ok(slam.finish());
    let poses = ok(slam.trajectory());
    let first = sequence.pose(0).inverse();
    let records = slam.records();
    let error_at = |index: usize| -> f64 {
        let Some(shows) = inputs[index].shows else {
            return f64::NAN;
        };
        let truth = first * sequence.pose(shows);
        (poses[index].1.to_isometry().translation.vector - truth.translation.vector).norm()
    };
    let revisit: Vec<_> = (DRIVEN + BLACK..inputs.len())
        .map(|i| {
            let r = &records[i];
            (
                i,
                inputs[i].shows.unwrap_or(usize::MAX),
                r.state,
                r.method,
                r.map,
                error_at(i),
            )
        })
        .collect();
    let relocalised = revisit
        .iter()
        .find(|r| r.3 == TrackingMethod::Relocalisation)
        .map(|r| r.0);
    let keyframes_before: Vec<usize> = {
        let first_map = slam
            .atlas()
            .get(0)
            .unwrap_or_else(|| panic!("no first map"));
        let map = ok(first_map.map.read().map_err(|_| "poisoned map"));
        let mut frames: Vec<usize> = map
            .keyframes()
            .map(|k| k.frame_index)
            .filter(|&f| f < DRIVEN)
            .collect();
        frames.sort_unstable();
        frames
    };
    Run {
        relocalised,
        error_m: relocalised.map_or(f64::NAN, error_at),
        inliers: relocalised.map_or(0, |i| records[i].inliers),
        revisit,
        keyframes_before,
        maps: slam.atlas().maps().len(),
        database: loop_closing,
    }
}

/// Live keyframes of the driven part made on the revisited road, and newer.
fn revisited_road(run: &Run) -> (usize, usize) {
    let on_road = run
        .keyframes_before
        .iter()
        .filter(|&&f| f < REVISIT_FROM + REVISIT)
        .count();
    (on_road, run.keyframes_before.len() - on_road)
}

fn print(run: &Run) {
    let name = if run.database {
        "keyframe database (loop closing on)"
    } else {
        "30-newest scan (loop closing off)"
    };
    let (on_road, newer) = revisited_road(run);
    eprintln!(
        "{name}: {} live keyframes of the first map before the blackout: {} on the revisited road (frames < {}), {} newer; relocalised at input {:?} (error {:.3} m, {} inliers); {} map(s)",
        run.keyframes_before.len(),
        on_road,
        REVISIT_FROM + REVISIT,
        newer,
        run.relocalised,
        run.error_m,
        run.inliers,
        run.maps
    );
    for (input, shows, state, method, map, error) in &run.revisit {
        eprintln!(
            "  input {input} (frame {shows}): {state:?} by {method:?}, map {map}, error {error:.3} m"
        );
    }
}

#[test]
fn relocalisation_finds_a_place_left_more_than_30_keyframes_ago() {
    let test = "relocalisation_finds_a_place_left_more_than_30_keyframes_ago";
    if !common::model_available(test) {
        return;
    }
    let sequence = small_sequence(SceneName::Loop, DRIVEN);
    let with = run(&sequence, true);
    print(&with);
    let without = run(&sequence, false);
    print(&without);

    // The revisited road is older than the scan reaches.
    let (on_road, newer) = revisited_road(&with);
    assert!(
        on_road > 0 && newer >= MAX_SCANNED_KEYFRAMES,
        "{on_road} keyframes on the revisited road, {newer} newer: the scan of the newest {MAX_SCANNED_KEYFRAMES} would reach them"
    );
    let first_real = DRIVEN + BLACK;
    let relocalised = with
        .relocalised
        .unwrap_or_else(|| panic!("not relocalised with the keyframe database"));
    assert!(
        relocalised < first_real + WITHIN,
        "relocalised at input {relocalised}, the first real frame is {first_real}"
    );
    assert!(
        with.revisit
            .iter()
            .all(|&(input, .., map, _)| map == 0 || input > relocalised),
        "a new map was started before relocalisation"
    );
    assert_eq!(with.maps, 1, "a new map was started");
    assert!(
        with.error_m <= MAX_ERROR_M,
        "relocalised {:.3} m from the truth",
        with.error_m
    );
    // Tracking goes on from there.
    let after: Vec<_> = with.revisit.iter().filter(|r| r.0 >= relocalised).collect();
    assert!(
        after.iter().all(|r| r.2 == TrackingState::Ok),
        "lost again after relocalising"
    );
}
