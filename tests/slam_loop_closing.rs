//! Loop closing on synthetic sequences with exact ground truth, SuperPoint
//! with ANMS on one level (int8), 480×360, local mapping inline
//! (deterministic), the default codebook `models/vlad_k64.spvlad`:
//!
//! - two laps of the city block: the revisit of the start is closed within
//!   5 keyframes of re-entry; the ATE with loop closing is at most 0.1 % of
//!   the path; at the revisit (the loop's two frames) the relative-pose
//!   error is at most 1/4 of the same run's without loop closing (the
//!   drift it found), at most 3 cm and 0.2°, and the correction matches
//!   that drift within 25 %. (A ratio of whole-run ATEs depended on how far
//!   the run without loop closing happened to drift, which differs between
//!   CPU kinds: 0.19 on an Intel with VNNI, 0.77 on an AVX2-only AMD.)
//! - the straight street, the highway and the aliasing street (two
//!   identical-looking places at different poses): no loop accepted;
//! - kidnapping: the first lap and the start of the second with blank
//!   frames early in the first lap: tracking is lost, a new map starts,
//!   and the revisit of the first map's area merges the two maps into
//!   one; the ATE over the frames with a pose is at most 0.1 % of the path;
//! - the kidnapped run again with local mapping and loop detection on
//!   their own threads (as `spslam run`): merged, one map at the end, ATE
//!   within 0.3 % of the path.
//!
//! Every measured value is printed (`--nocapture`). The inline runs share
//! a feature cache (`common::feature_cache`): each image is extracted once.

mod common;

use std::ops::Range;
use std::sync::Arc;
use std::time::{Duration, Instant};

use nalgebra::Isometry3;

use common::synthetic_slam::{cached_images, images, rig_of, small_sequence};
use spslam::dataset::synthetic::{SceneName, SyntheticSequence};
use spslam::eval::{evaluate, EvalOptions, Pairing, Trajectory};
use spslam::loop_closing::LoopThresholds;
use spslam::place::{default_codebook_for, Codebook};
use spslam::settings::ExtractorSettings;
use spslam::system::LoopCandidateRecord;
use spslam::system::{LoopRecord, MergeRecord, SlamSystem};
use spslam::tracking::Frontend;
use spslam::tracking::TrackingState;

fn ok<T, E: std::fmt::Display>(r: Result<T, E>) -> T {
    r.unwrap_or_else(|e| panic!("{e}"))
}

/// What one run gave.
struct Run {
    ate_m: f64,
    /// ATE over the frames tracked (a gap's frames have no pose of their own).
    ate_tracked_m: f64,
    path_m: f64,
    loops: Vec<LoopRecord>,
    merges: Vec<MergeRecord>,
    /// Every loop and merge candidate checked, each stage counted.
    candidates: Vec<LoopCandidateRecord>,
    /// Atlas maps not merged into another at the end.
    live_maps: usize,
    keyframe_frames: Vec<usize>,
    lost: Vec<usize>,
    /// `T_c0,ci` per frame: the estimate (after the run) and the truth.
    estimate: Vec<Isometry3<f64>>,
    truth: Vec<Isometry3<f64>>,
}

impl Run {
    /// The error of the relative pose between frames `a` and `b` (metres,
    /// degrees): `(T_a,b true)⁻¹ · T_a,b estimated`. At a revisit this is
    /// what a loop closure is there to remove, whatever the drift that led
    /// to it.
    fn relative_error(&self, a: usize, b: usize) -> (f64, f64) {
        let relative = |poses: &[Isometry3<f64>]| poses[a].inverse() * poses[b];
        let error = relative(&self.truth).inverse() * relative(&self.estimate);
        (
            error.translation.vector.norm(),
            error.rotation.angle().to_degrees(),
        )
    }
}

/// SuperPoint stereo SLAM over the whole sequence, loop closing on or off,
/// the frames in `blank` replaced by black images.
fn run(sequence: &SyntheticSequence, loop_closing: bool, blank: Range<usize>) -> Run {
    run_on(sequence, loop_closing, blank, false, sequence.len())
}

/// [`run`], with local mapping and loop detection on their own threads
/// when `threaded` (as `spslam run`; not deterministic).
fn run_on(
    sequence: &SyntheticSequence,
    loop_closing: bool,
    blank: Range<usize>,
    threaded: bool,
    frames: usize,
) -> Run {
    let rig = rig_of(sequence);
    let config = ExtractorSettings::default().superpoint_config(1, 1);
    // Inline runs see the same images again (with and without loop
    // closing, with the gap): each is extracted once. A threaded run
    // extracts every frame, so the mapping thread lags as in `spslam run`.
    let mut slam = if threaded {
        let sp = || Box::new(common::extractor(config.clone()));
        SlamSystem::new(rig, Frontend::new(sp(), sp(), &rig))
    } else {
        let sp = || Box::new(common::cached_extractor(config.clone()));
        SlamSystem::new(rig, Frontend::new(sp(), sp(), &rig))
    };
    if threaded {
        ok(slam.spawn_mapping_thread());
    }
    if loop_closing {
        let codebook = ok(Codebook::load_for(&default_codebook_for(&config), &config));
        // Every candidate through every stage: the verdicts are the same
        // (`LoopStageCounts::first_failing`), and the records are checked.
        let thresholds = LoopThresholds {
            record_every_stage: true,
            ..LoopThresholds::default()
        };
        ok(slam.enable_loop_closing(Arc::new(codebook.vlad), thresholds));
    }
    let first = sequence.pose(0).inverse();
    let mut truth = Vec::new();
    let started = Instant::now();
    let mut rendering = Duration::ZERO;
    for i in 0..frames.min(sequence.len()) {
        let render_started = Instant::now();
        let (t, mut l, mut r) = if threaded {
            images(sequence, i)
        } else {
            cached_images(sequence, i)
        };
        if blank.contains(&i) {
            l = black(&l);
            r = black(&r);
        }
        rendering += render_started.elapsed();
        ok(slam.process(i, t, l.view(), r.view()));
        truth.push((t, first * sequence.pose(i)));
    }
    ok(slam.finish());
    eprintln!(
        "  run of {} frames (loop closing {loop_closing}, threaded {threaded}): {:.1} s, rendering {:.1} s; features cached/extracted so far {:?}",
        truth.len(),
        started.elapsed().as_secs_f64(),
        rendering.as_secs_f64(),
        common::feature_cache::hits_and_misses()
    );
    let poses = ok(slam.trajectory());
    let every = vec![true; poses.len()];
    let tracked: Vec<bool> = slam
        .records()
        .iter()
        .map(|r| r.state == TrackingState::Ok)
        .collect();
    let ate = |keep: &[bool]| {
        let estimate = Trajectory::new(
            keep_rows(&poses, keep, |(t, _)| *t),
            keep_rows(&poses, keep, |(_, p)| p.to_isometry()),
        );
        let reference = Trajectory::new(
            keep_rows(&truth, keep, |(t, _)| *t),
            keep_rows(&truth, keep, |(_, p)| *p),
        );
        // A straight path cannot be aligned (Umeyama is degenerate): no ATE there.
        evaluate(
            &reference,
            &estimate,
            &EvalOptions {
                pairing: Pairing::ByIndex,
                ..EvalOptions::default()
            },
        )
        .map_or((f64::NAN, f64::NAN), |r| (r.ate.se3_rmse, r.path_length_m))
    };
    let (ate_m, path_m) = ate(&every);
    let (ate_tracked_m, _) = ate(&tracked);
    for r in slam.rejected_loops() {
        eprintln!(
            "  rejected candidate: frame {} -> {} score {:.3} at {:?} ({})",
            r.query_frame, r.candidate_frame, r.score, r.stage, r.count
        );
    }
    for g in slam.global_ba_runs() {
        eprintln!("  global BA: {g:?}");
    }
    Run {
        ate_m,
        ate_tracked_m,
        path_m,
        loops: slam.loops().to_vec(),
        merges: slam.merges().to_vec(),
        candidates: slam.loop_candidates().to_vec(),
        live_maps: slam
            .atlas()
            .maps()
            .iter()
            .filter(|m| m.merged_into.is_none())
            .count(),
        keyframe_frames: slam
            .records()
            .iter()
            .filter(|r| r.keyframe)
            .map(|r| r.index)
            .collect(),
        lost: common::untracked(slam.records()),
        estimate: poses.iter().map(|(_, p)| p.to_isometry()).collect(),
        truth: truth.iter().map(|(_, p)| *p).collect(),
    }
}

/// The rows of `rows` whose `keep` flag is set, mapped by `f`.
fn keep_rows<T, U>(rows: &[T], keep: &[bool], f: impl Fn(&T) -> U) -> Vec<U> {
    rows.iter()
        .zip(keep)
        .filter(|(_, k)| **k)
        .map(|(r, _)| f(r))
        .collect()
}

/// A black image of `image`'s size.
fn black(image: &spslam::features::GrayImage) -> spslam::features::GrayImage {
    let (w, h) = (image.width(), image.height());
    ok(spslam::features::GrayImage::from_vec(vec![0; w * h], w, h))
}

/// The kidnapped runs stop this many frames into the second lap: the
/// merge comes at the revisit, a few frames before the lap ends.
const AFTER_REVISIT: usize = 40;

/// Frames in one lap of the loop scene (a whole number: the scene rounds
/// the step).
fn lap_frames() -> usize {
    let one_lap = small_sequence(SceneName::Loop, 1);
    (0..2000)
        .skip(10)
        .find(|&i| {
            (one_lap.pose(i).translation.vector - one_lap.pose(0).translation.vector).norm() < 1e-6
        })
        .unwrap_or_else(|| panic!("the loop scene does not return to its start"))
}

#[test]
fn two_laps_of_the_block_close_the_loop_and_cut_the_error_and_a_gap_merges() {
    let test = "two_laps_of_the_block_close_the_loop_and_cut_the_error_and_a_gap_merges";
    if !common::model_available(test) {
        return;
    }
    let lap_frames = lap_frames();
    let sequence = small_sequence(SceneName::Loop, 2 * lap_frames + 10);
    let with = run(&sequence, true, 0..0);
    let first = with
        .loops
        .first()
        .unwrap_or_else(|| panic!("no loop closed over two laps: {:?}", with.loops));
    // Without loop closing, up to the loop's frame: that is all it is compared on.
    let without = run_on(&sequence, false, 0..0, false, first.query_frame + 1);
    // The error at the revisit, the loop's two frames: the run without loop
    // closing is the same run up to the loop (local mapping inline,
    // deterministic), so its error there is the drift the loop found.
    let (before_m, before_deg) = without.relative_error(first.match_frame, first.query_frame);
    let (after_m, after_deg) = with.relative_error(first.match_frame, first.query_frame);
    eprintln!(
        "two laps ({} frames, lap {lap_frames}, path {:.1} m): ATE with loop closing {:.4} m ({:.3} % of the path), without (up to the loop) {:.4} m; revisit {} -> {}: error without {before_m:.4} m / {before_deg:.3} deg, with {after_m:.4} m / {after_deg:.3} deg; loops {:?}",
        sequence.len(),
        with.path_m,
        with.ate_m,
        100.0 * with.ate_m / with.path_m,
        without.ate_m,
        first.query_frame,
        first.match_frame,
        with.loops
            .iter()
            .map(|l| (l.query_frame, l.match_frame, l.inliers, l.correction_m, l.correction_deg))
            .collect::<Vec<_>>()
    );
    assert!(with.lost.is_empty(), "frames lost: {:?}", with.lost);
    assert_candidates_recorded(&with);
    assert_passing_candidates_register_right(&with);
    assert!(
        with.candidates
            .iter()
            .any(|c| c.rejected_at.is_none() && c.candidate_frame == first.match_frame),
        "the loop's candidate (frame {}) is not recorded as verified",
        first.match_frame
    );
    assert!(with.ate_m.is_finite() && without.ate_m.is_finite());
    assert!(without.loops.is_empty());
    // Re-entry: the start of the second lap; five keyframes later at most.
    let deadline = with
        .keyframe_frames
        .iter()
        .filter(|&&f| f >= lap_frames)
        .nth(4)
        .copied()
        .unwrap_or(usize::MAX);
    assert!(
        first.query_frame <= deadline,
        "first loop at frame {}, re-entry at {lap_frames}, fifth keyframe after it at {deadline}",
        first.query_frame
    );
    assert!(
        first.match_frame < lap_frames / 10,
        "the loop matched frame {}, not the start",
        first.match_frame
    );
    // Measured: 0.024 % (Intel, AVX-512 VNNI), 0.044 % (AMD, AVX2 only).
    assert!(
        with.ate_m <= 0.001 * with.path_m,
        "ATE {} m over {} m",
        with.ate_m,
        with.path_m
    );
    // What the loop closure controls, whatever the drift before it (which
    // differs between CPU kinds: the int8 network's rounding differs).
    // Measured (Intel, VNNI): 0.336 m / 0.201 deg without, 0.0064 m /
    // 0.031 deg with, a correction of 0.332 m.
    assert!(
        after_m <= 0.25 * before_m && after_m <= 0.03 && after_deg <= 0.2,
        "the error at the revisit: {after_m} m / {after_deg} deg with loop closing, {before_m} m without"
    );
    assert!(
        (first.correction_m - before_m).abs() <= 0.25 * before_m,
        "the correction ({} m) does not undo the drift found at the revisit ({before_m} m)",
        first.correction_m
    );
    assert_kidnapped_run_merges(&sequence, lap_frames, &with);
}

/// No loop on a scene that never revisits a place.
/// Each recorded candidate's verdict is the one its counts give at the
/// default thresholds, and a candidate rejected at the descriptor stage was
/// still taken as far as its geometry allowed (RANSAC tried).
fn assert_candidates_recorded(run: &Run) {
    let th = LoopThresholds::default();
    assert!(!run.candidates.is_empty(), "no loop candidate recorded");
    for c in &run.candidates {
        assert_eq!(
            c.rejected_at,
            c.counts.first_failing(&th).map(|(stage, _)| stage),
            "{c:?}"
        );
        if c.rejected_at.is_none() {
            assert!(c.candidate_in_query.is_some(), "{c:?}");
        }
    }
    let furthest = run
        .candidates
        .iter()
        .filter(|c| c.rejected_at.is_some())
        .max_by_key(|c| c.counts.reprojection_inliers);
    eprintln!(
        "  {} candidates recorded; {} with a RANSAC pose; the rejected one with the most final inliers: {furthest:?}",
        run.candidates.len(),
        run.candidates.iter().filter(|c| c.counts.ransac_inliers.is_some()).count()
    );
}

/// The candidates that pass the geometric check register the candidate
/// camera where the ground truth has it: within 1 m in the query camera's
/// frame (a look-alike registers tens of metres off). Confirmation by later
/// keyframes is not counted on.
fn assert_passing_candidates_register_right(run: &Run) {
    for c in run.candidates.iter().filter(|c| c.rejected_at.is_none()) {
        let [x, y, z] = c
            .candidate_in_query
            .unwrap_or_else(|| panic!("a passing candidate has a pose: {c:?}"));
        let truth = run.truth[c.query_frame].inverse() * run.truth[c.candidate_frame];
        let error = (truth.translation.vector - nalgebra::Vector3::new(x, y, z)).norm();
        assert!(
            error <= 1.0,
            "candidate frame {} passed the check for frame {} registered {error:.2} m off the truth: {c:?}",
            c.candidate_frame,
            c.query_frame
        );
    }
}

fn assert_no_loop(scene: SceneName, frames: usize) {
    let sequence = small_sequence(scene, frames);
    let result = run(&sequence, true, 0..0);
    assert_candidates_recorded(&result);
    assert_passing_candidates_register_right(&result);
    eprintln!(
        "{scene:?}, {frames} frames: {} loops, ATE {:.4} m, lost {:?}",
        result.loops.len(),
        result.ate_m,
        result.lost
    );
    assert!(
        result.loops.is_empty(),
        "false loops on {scene:?}: {:?}",
        result
            .loops
            .iter()
            .map(|l| (l.query_frame, l.match_frame, l.inliers))
            .collect::<Vec<_>>()
    );
}

#[test]
fn no_loop_on_the_straight_street() {
    if common::model_available("no_loop_on_the_straight_street") {
        assert_no_loop(SceneName::Straight, 150);
    }
}

#[test]
fn no_loop_on_the_highway() {
    if common::model_available("no_loop_on_the_highway") {
        assert_no_loop(SceneName::Highway, 200);
    }
}

#[test]
fn no_loop_between_two_identical_looking_places() {
    if common::model_available("no_loop_between_two_identical_looking_places") {
        assert_no_loop(SceneName::Aliasing, 230);
    }
}

/// The two-lap sequence again, up to [`AFTER_REVISIT`] frames into the
/// second lap, with black frames early in the first lap: the maps are
/// merged at the revisit and the ATE over the frames with a pose is at
/// most 0.1 % of the path (`reference`, the two laps without the gap, is
/// printed beside it). (Part of the two-lap test, which has the reference
/// run and the features already: a run of this sequence takes minutes.)
fn assert_kidnapped_run_merges(sequence: &SyntheticSequence, lap_frames: usize, reference: &Run) {
    // Black frames a quarter into the first lap: the camera moves on
    // unseen, tracking is lost and a new map starts after the gap.
    let gap = lap_frames / 4..lap_frames / 4 + 25;
    let kidnapped = run_on(
        sequence,
        true,
        gap.clone(),
        false,
        lap_frames + AFTER_REVISIT,
    );
    eprintln!(
        "kidnapped lap (gap {gap:?}, lap {lap_frames}, {} frames, path {:.1} m): ATE over tracked frames {:.4} m ({:.3} % of the path; two laps without the gap {:.4} m); merges {:?}; loops {:?}; maps left {}; untracked {:?}",
        kidnapped.truth.len(),
        kidnapped.path_m,
        kidnapped.ate_tracked_m,
        100.0 * kidnapped.ate_tracked_m / kidnapped.path_m,
        reference.ate_tracked_m,
        kidnapped
            .merges
            .iter()
            .map(|m| (m.query_frame, m.match_frame, m.merged_map, m.into_map, m.inliers))
            .collect::<Vec<_>>(),
        kidnapped
            .loops
            .iter()
            .map(|l| (l.query_frame, l.match_frame, l.inliers))
            .collect::<Vec<_>>(),
        kidnapped.live_maps,
        kidnapped.lost,
    );
    assert!(
        kidnapped.lost.iter().any(|f| gap.contains(f)),
        "the gap did not lose tracking"
    );
    assert!(
        kidnapped.lost.iter().all(|f| *f < gap.end + 10),
        "frames lost long after the gap: {:?}",
        kidnapped.lost
    );
    let merge = kidnapped
        .merges
        .first()
        .unwrap_or_else(|| panic!("the maps were not merged"));
    assert_eq!((merge.merged_map, merge.into_map), (1, 0));
    // The first map's start comes into view a few frames before the lap
    // ends (the path closes smoothly).
    assert!(
        merge.query_frame + 10 >= lap_frames && merge.match_frame < gap.start,
        "merge at frame {} with frame {}: not the revisit of the first map",
        merge.query_frame,
        merge.match_frame
    );
    assert_eq!(kidnapped.live_maps, 1, "the run did not end as one map");
    assert_merge_judged_by_the_handover(&kidnapped, merge, gap.start - 1);
    // Measured (Intel, VNNI): 0.0892 m, 0.033 % of the 270 m path (threaded:
    // 0.0902 m); merged at frame 228 with frame 0.
    assert!(
        kidnapped.ate_tracked_m <= 0.001 * kidnapped.path_m,
        "ATE {} m with the gap over {} m ({} m without the gap)",
        kidnapped.ate_tracked_m,
        kidnapped.path_m,
        reference.ate_tracked_m
    );
}

/// The accepted merge into the map the camera was lost from (after frame
/// `last_tracked`) was judged by where it puts the new map next to where
/// the camera was lost: its measured gap is the true way between the two
/// frames, and within what the stage allows.
fn assert_merge_judged_by_the_handover(run: &Run, merge: &MergeRecord, last_tracked: usize) {
    let judged = run
        .candidates
        .iter()
        .filter(|c| c.query_frame == merge.query_frame && c.other_map == Some(merge.into_map))
        .find(|c| c.rejected_at.is_none() && c.candidate_frame == merge.match_frame)
        .unwrap_or_else(|| panic!("no record of the accepted merge's check"));
    let gap = judged
        .counts
        .handover
        .unwrap_or_else(|| panic!("the merge was not judged by the handover"));
    let first = last_tracked + gap.frames;
    let true_gap_m =
        (run.truth[first].translation.vector - run.truth[last_tracked].translation.vector).norm();
    let th = LoopThresholds::default();
    eprintln!(
        "handover: gap {:.2} m (true {true_gap_m:.2} m) over {} frames at {:.3} m/frame, drift path {:.1} m, depth {:.1} m; allowed {:.2} m",
        gap.gap_m,
        gap.frames,
        gap.speed_m_per_frame,
        gap.drift_path_m,
        gap.scene_depth_m,
        gap.allowed_m(&th)
    );
    assert!(gap.excess(&th) <= 1.0);
    assert!(
        (gap.gap_m - true_gap_m).abs() <= 0.05 * true_gap_m,
        "measured gap {:.2} m, true {true_gap_m:.2} m",
        gap.gap_m
    );
}

#[test]
fn a_kidnapped_run_with_mapping_and_loop_threads_merges_its_maps() {
    let test = "a_kidnapped_run_with_mapping_and_loop_threads_merges_its_maps";
    if !common::model_available(test) {
        return;
    }
    let lap_frames = lap_frames();
    let sequence = small_sequence(SceneName::Loop, 2 * lap_frames + 10);
    let gap = lap_frames / 4..lap_frames / 4 + 25;
    let threaded = run_on(
        &sequence,
        true,
        gap.clone(),
        true,
        lap_frames + AFTER_REVISIT,
    );
    eprintln!(
        "threads, kidnapped lap (gap {gap:?}): ATE over tracked frames {:.4} m ({:.3} % of {:.1} m); merges {:?}; loops {:?}; maps left {}; untracked {}",
        threaded.ate_tracked_m,
        100.0 * threaded.ate_tracked_m / threaded.path_m,
        threaded.path_m,
        threaded
            .merges
            .iter()
            .map(|m| (m.query_frame, m.match_frame, m.merged_map, m.into_map, m.inliers))
            .collect::<Vec<_>>(),
        threaded
            .loops
            .iter()
            .map(|l| (l.query_frame, l.match_frame, l.inliers))
            .collect::<Vec<_>>(),
        threaded.live_maps,
        threaded.lost.len(),
    );
    let merge = threaded
        .merges
        .first()
        .unwrap_or_else(|| panic!("the maps were not merged"));
    assert_eq!(threaded.live_maps, 1, "the run did not end as one map");
    assert_merge_judged_by_the_handover(&threaded, merge, gap.start - 1);
    assert!(
        threaded.lost.iter().all(|f| *f < gap.end + 10),
        "frames lost long after the gap: {:?}",
        threaded.lost
    );
    assert!(
        threaded.ate_tracked_m <= 0.003 * threaded.path_m,
        "ATE {} m over {} m",
        threaded.ate_tracked_m,
        threaded.path_m
    );
}
