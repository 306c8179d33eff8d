//! One loop-candidate verification (`spslam::loop_closing::verify_candidate`:
//! descriptor matching against the candidate group, PnP RANSAC, pose
//! optimisation, search by projection, final optimisation) on the real
//! EuRoC V1_01 loop pair (`euroc/V1_01_easy_loop_pairs/`).
//!
//! The map is the one `tests/loop_pair_euroc.rs` builds
//! (`tests/common/euroc_loop_pair.rs`): keyframe A (`match1`) at the origin
//! and keyframe B (`query1`, the same place 98 s later) 3 m and 20° off
//! the ground truth, each with its own stereo points; plus keyframe C
//! (`match2`, another part of the room, 3.4 m from `query1` and facing
//! elsewhere). Benchmarks:
//!
//! - `verified_query1_match1`: B against A, a true loop that passes every
//!   stage (the most work a candidate can cost);
//! - `rejected_query1_match2`: B against C, a different place, as most
//!   candidates are.
//!
//! Before the criterion group it prints each check's outcome (inliers or the
//! stage that rejected it). Without the data or the model it prints a line
//! and measures nothing.
use std::path::PathBuf;
use std::time::Instant;

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use spslam::eval::read_tum;
use spslam::features::{default_model_path, Precision};
use spslam::loop_closing::{verify_candidate, LoopThresholds, Verification};
use spslam::map::{KeyFrameId, Map};
use spslam::optim::Se3;

#[path = "../tests/common/euroc_loop_pair.rs"]
mod euroc_loop_pair;

use euroc_loop_pair::{
    add_keyframe, build_loop_map, euroc_rig, openvins_pose, read_pairs, role, EurocRig, OPENVINS_GT,
};

/// The data folder: `SPSLAM_DATA`, else `../shared/data` next to the crate.
fn data_root() -> PathBuf {
    std::env::var_os("SPSLAM_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data"))
}

fn describe(v: &Verification) -> String {
    match v {
        Verification::Verified(v) => format!(
            "verified, {} inliers ({} matched points, group {:?})",
            v.inliers,
            v.matches.iter().flatten().count(),
            v.group
        ),
        Verification::Rejected { stage, count } => format!("rejected at {stage:?} ({count})"),
    }
}

/// Runs one check untimed by criterion, prints its outcome and wall time.
fn check(name: &str, map: &Map, query: KeyFrameId, candidate: KeyFrameId, rig: &EurocRig) {
    let th = LoopThresholds::default();
    let start = Instant::now();
    let v = verify_candidate(map, query, candidate, &rig.rig, &th)
        .unwrap_or_else(|e| panic!("verify_candidate: {e}"));
    println!(
        "loop_verify: {name}: {} in {:.2} ms (first call)",
        describe(&v),
        start.elapsed().as_secs_f64() * 1e3
    );
}

fn bench(c: &mut Criterion) {
    let root = data_root();
    let dir = match euroc_loop_pair::pair_dir(&root) {
        Ok(dir) => dir,
        Err(what) => {
            println!("loop_verify: skipped, {what} is missing (set SPSLAM_DATA)");
            return;
        }
    };
    let model = Precision::Int8.default_model_path();
    if !model.is_file() || !default_model_path().is_file() {
        println!(
            "loop_verify: skipped, the SuperPoint model ({}) is missing (run `make setup`)",
            model.display()
        );
        return;
    }
    let pairs = read_pairs(&dir);
    let (matched, query, other) = (
        role(&pairs, "match1"),
        role(&pairs, "query1"),
        role(&pairs, "match2"),
    );
    let rig = euroc_rig(&dir);
    // B's ground-truth pose in A's frame: OpenVINS's where the excerpt ships
    // it (as the test), else pairs.txt's. The check does not depend on it
    // (RANSAC finds B's pose from the matches alone).
    let gt_path = root.join(OPENVINS_GT);
    let truth = if gt_path.is_file() {
        let gt = read_tum(&gt_path).unwrap_or_else(|e| panic!("{}: {e}", gt_path.display()));
        rig.relative(
            openvins_pose(&gt, matched.timestamp_ns),
            openvins_pose(&gt, query.timestamp_ns),
        )
    } else {
        rig.relative(matched.t_wb, query.t_wb)
    };
    let mut fe = euroc_loop_pair::frontend(&rig);
    let mut built = build_loop_map(&mut fe, &rig, matched, query, &truth);
    let c_pose = Se3::from_isometry(&rig.relative(matched.t_wb, other.t_wb));
    let kc = add_keyframe(&mut built.map, &mut fe, &rig, 2, other, c_pose);
    let (map, a, b) = (&built.map, built.a, built.b);
    println!(
        "loop_verify: A (match1) {} keypoints / {} points, B (query1) {} / {}, C (match2) {} / {}",
        a.keypoints, a.points, b.keypoints, b.points, kc.keypoints, kc.points
    );
    check("query1 vs match1", map, b.id, a.id, &rig);
    check("query1 vs match2", map, b.id, kc.id, &rig);

    let th = LoopThresholds::default();
    let mut g = c.benchmark_group("loop_verify");
    g.sample_size(10);
    for (name, candidate) in [
        ("verified_query1_match1", a.id),
        ("rejected_query1_match2", kc.id),
    ] {
        g.bench_function(name, |bench| {
            bench.iter(|| {
                verify_candidate(map, black_box(b.id), black_box(candidate), &rig.rig, &th)
                    .unwrap_or_else(|e| panic!("verify_candidate: {e}"))
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
