//! Retrieval study: where does VLAD rank the true earlier view of a
//! revisiting frame, for several ways of querying the keyframe database?
//!
//! ```sh
//! cargo run --release --example place_study -- SYNTH_DIR [CACHE_FILE]
//! ```
//!
//! SYNTH_DIR is a `spslam synth` output (left images and poses). Features
//! are cached in CACHE_FILE (default SYNTH_DIR/place_study.bin). A query
//! revisits when an earlier frame, at least 30 frames older, lies within
//! 3 m and 20° of it; its true views are those frames. The database holds
//! every frame older than 10 frames. Prints the database query's recall@3
//! for several score ratios and group sizes, and recall@1/@3/@10 of plain
//! ranking by similarity.

use std::io::{Read, Write};
use std::path::PathBuf;

use spslam::features::{GrayImage, SuperPointExtractor};
use spslam::place::{Codebook, GlobalDescriptor};
use spslam::settings::{ExtractorSettings, DEFAULT_SUPERPOINT_LEVELS};

struct Frame {
    descriptors: Vec<f32>,
}

fn load_poses(path: &std::path::Path) -> anyhow::Result<Vec<[f64; 12]>> {
    let text = std::fs::read_to_string(path)?;
    text.lines()
        .filter(|l| !l.trim().is_empty())
        .enumerate()
        .map(|(i, l)| {
            let v: Vec<f64> = l
                .split_whitespace()
                .map(str::parse)
                .collect::<Result<_, _>>()
                .map_err(|e| anyhow::anyhow!("{}: line {}: {e}", path.display(), i + 1))?;
            <[f64; 12]>::try_from(v.as_slice())
                .map_err(|_| anyhow::anyhow!("{}: line {}: not 12 numbers", path.display(), i + 1))
        })
        .collect()
}

fn features(dir: &std::path::Path, cache: &std::path::Path) -> anyhow::Result<Vec<Frame>> {
    if let Ok(mut f) = std::fs::File::open(cache) {
        let mut bytes = Vec::new();
        f.read_to_end(&mut bytes)?;
        let mut frames = Vec::new();
        let mut at = 0;
        let u32_at = |b: &[u8], i: usize| -> anyhow::Result<u32> {
            b.get(i..i + 4)
                .and_then(|w| <[u8; 4]>::try_from(w).ok())
                .map(u32::from_le_bytes)
                .ok_or_else(|| anyhow::anyhow!("{} is truncated: delete it", cache.display()))
        };
        while at < bytes.len() {
            let n = u32_at(&bytes, at)? as usize;
            at += 4;
            let mut descriptors = Vec::with_capacity(n * 256);
            for _ in 0..n * 256 {
                descriptors.push(f32::from_bits(u32_at(&bytes, at)?));
                at += 4;
            }
            frames.push(Frame { descriptors });
        }
        return Ok(frames);
    }
    let config = study_config();
    let mut extractor = SuperPointExtractor::new(config)?;
    let mut images: Vec<PathBuf> = std::fs::read_dir(dir.join("sequences/00/image_0"))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .collect();
    images.sort();
    let mut frames = Vec::new();
    let mut out = std::fs::File::create(cache)?;
    for p in &images {
        let img = GrayImage::load(p)?;
        let f = extractor.extract(img.view())?;
        out.write_all(&(f.keypoints.len() as u32).to_le_bytes())?;
        for d in &f.descriptors {
            out.write_all(&d.to_bits().to_le_bytes())?;
        }
        frames.push(Frame {
            descriptors: f.descriptors,
        });
    }
    Ok(frames)
}

/// The extractor's defaults; `STUDY_MODEL=photo|lite` picks a named model.
fn study_config() -> spslam::features::ExtractorConfig {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mut config =
        ExtractorSettings::default().superpoint_config(DEFAULT_SUPERPOINT_LEVELS, cores);
    if let Ok(name) = std::env::var("STUDY_MODEL") {
        config.model_path = Some(PathBuf::from(name));
    }
    config
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(dir) = args.first().map(PathBuf::from) else {
        anyhow::bail!("usage: place_study SYNTH_DIR [CACHE_FILE]");
    };
    let cache = args
        .get(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| dir.join("place_study.bin"));
    let frames = features(&dir, &cache)?;
    let poses = load_poses(&dir.join("poses/00.txt"))?;
    let codebook = Codebook::load(&spslam::place::default_codebook_for(&study_config()))?;
    let vlad = &codebook.vlad;
    let n = frames.len();
    // Truth.
    let angle = |a: &[f64; 12], b: &[f64; 12]| {
        // rotation angle between the two camera orientations
        let mut tr = 0.0;
        for i in 0..3 {
            for j in 0..3 {
                tr += a[i * 4 + j] * b[i * 4 + j];
            }
        }
        ((tr - 1.0) / 2.0).clamp(-1.0, 1.0).acos().to_degrees()
    };
    let dist = |a: &[f64; 12], b: &[f64; 12]| {
        ((a[3] - b[3]).powi(2) + (a[7] - b[7]).powi(2) + (a[11] - b[11]).powi(2)).sqrt()
    };
    let truth: Vec<Vec<usize>> = (0..n)
        .map(|i| {
            (0..i.saturating_sub(30))
                .filter(|&j| dist(&poses[i], &poses[j]) < 3.0 && angle(&poses[i], &poses[j]) < 20.0)
                .collect()
        })
        .collect();
    let queries: Vec<usize> = (0..n).filter(|&i| !truth[i].is_empty()).collect();
    println!("{n} frames, {} revisiting queries", queries.len());

    let g: Vec<Option<Vec<f32>>> = frames
        .iter()
        .map(|f| vlad.compute_flat(&f.descriptors).ok())
        .collect();
    // The keyframe database's grouped query, as `spslam loops` runs it.
    {
        for (ratio, group) in [(0.8f32, 10usize), (0.9, 10), (0.95, 10), (0.8, 0), (0.9, 4)] {
            let options = spslam::place::QueryOptions {
                n_best: 3,
                group_size: group,
                min_score_ratio: ratio,
            };
            let mut db = spslam::place::KeyframeDatabase::<usize>::new(vlad.dim())?;
            let mut inserted = 0;
            let mut hits = 0;
            for q in 0..n {
                while inserted + 10 < q {
                    if let Some(x) = &g[inserted] {
                        db.insert(inserted, x)?;
                    }
                    inserted += 1;
                }
                if truth[q].is_empty() {
                    continue;
                }
                let Some(gq) = &g[q] else { continue };
                let neighbours = |j: usize| -> Vec<usize> {
                    (1..=5)
                        .flat_map(|d| [j.checked_sub(d), Some(j + d)])
                        .flatten()
                        .collect()
                };
                let found =
                    db.query(gq, &std::collections::HashSet::new(), neighbours, &options)?;
                if found.iter().any(|c| truth[q].contains(&c.keyframe)) {
                    hits += 1;
                }
            }
            println!(
                "database query ratio {ratio} group {group}: recall@3 {:.3}",
                hits as f64 / queries.len().max(1) as f64
            );
        }
    }
    // Plain ranking by similarity (the VLADs are unit vectors), over every
    // frame older than the recent window.
    let mut hits = [0usize; 3];
    for &q in &queries {
        let Some(gq) = &g[q] else { continue };
        let mut ranked: Vec<(f32, usize)> = (0..q.saturating_sub(10))
            .filter_map(|j| {
                let x = g[j].as_ref()?;
                Some((gq.iter().zip(x).map(|(a, b)| a * b).sum::<f32>(), j))
            })
            .collect();
        ranked.sort_by(|a, b| b.0.total_cmp(&a.0));
        for (h, k) in hits.iter_mut().zip([1usize, 3, 10]) {
            if ranked.iter().take(k).any(|(_, j)| truth[q].contains(j)) {
                *h += 1;
            }
        }
    }
    let nq = queries.len().max(1) as f64;
    println!(
        "ranked by similarity: recall@1 {:.3} @3 {:.3} @10 {:.3}",
        hits[0] as f64 / nq,
        hits[1] as f64 / nq,
        hits[2] as f64 / nq
    );
    Ok(())
}
