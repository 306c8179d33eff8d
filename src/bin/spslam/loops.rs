//! `spslam loops`: place recognition plus geometric verification over a
//! folder of images in name order. For every image, the earlier images
//! (but the most recent ones) are searched with VLAD over SuperPoint
//! descriptors in a keyframe database, and the best candidates are verified
//! by a fundamental-matrix RANSAC. It shows whether the loops of a dataset
//! would be found.
//!
//! ORB-SLAM3 excludes the query keyframe's covisible keyframes (those
//! sharing map points with it). Without a map, the tool tracks keypoints
//! instead: each image's RANSAC inliers against the previous image continue
//! that image's tracks, and an earlier image sharing at least
//! [`MIN_SHARED_TRACKS`] tracks with the query is covisible and not searched
//! (ORB-SLAM3's covisibility-graph threshold is 15 shared points too). A
//! camera that stays in one place (the start of EuRoC V1_01) keeps its
//! tracks alive and is therefore never matched with itself, while a real
//! revisit, reached after the tracks have died, is searched.

mod verify;

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;
use spslam::features::{DescriptorSet, Device, GrayImage, SuperPointExtractor};
use spslam::place::{
    default_codebook_path, Codebook, GlobalDescriptor, KeyframeDatabase, PlaceError, QueryOptions,
};
use spslam::settings::{ExtractorSettings, DEFAULT_SUPERPOINT_LEVELS};

use crate::vocab::images::list_images;
use verify::{verify, ImageFeatures, Verification};

/// The inliers a candidate needs to be accepted. Measured with the default
/// codebook (README, "Place recognition codebook"): the EuRoC loop pair
/// (match1/query1, 98 s apart) verifies with 102 inliers of 171 matches;
/// the best rejected candidates are KITTI 06 frames 11 frames apart whose
/// views still overlap (47 and 39 inliers); the EuRoC excerpt leaves no
/// candidate after the covisibility exclusion. 60 sits between the two.
pub const DEFAULT_MIN_INLIERS: usize = 60;

/// Tracks an earlier image must share with the query to be covisible (not searched).
pub const MIN_SHARED_TRACKS: usize = 15;

/// The arguments of `spslam loops`.
#[derive(clap::Args)]
pub struct LoopsArgs {
    /// The folder of images (8-bit gray or colour PNG/JPEG), read in name order.
    #[arg(long)]
    images: PathBuf,
    /// Also write the accepted matches as JSON to this file.
    #[arg(long)]
    json: Option<PathBuf>,
    /// The VLAD codebook [default: SPSLAM_CODEBOOK, else models/vlad_k64.spvlad].
    #[arg(long)]
    codebook: Option<PathBuf>,
    /// The most recent earlier images that are not searched.
    #[arg(long, default_value_t = 10)]
    exclude_recent: usize,
    /// Candidates verified per image (the database's best groups).
    #[arg(long, default_value_t = 3)]
    candidates: usize,
    /// Fundamental-matrix inliers needed to accept a candidate.
    #[arg(long, default_value_t = DEFAULT_MIN_INLIERS)]
    min_inliers: usize,
    /// Where SuperPoint runs: auto, cpu or cuda.
    #[arg(long, default_value_t = Device::default())]
    device: Device,
}

/// The JSON file: every image with its accepted matches.
#[derive(Serialize)]
struct Report {
    images: Vec<ImageReport>,
}

#[derive(Serialize)]
struct ImageReport {
    image: String,
    matches: Vec<MatchReport>,
}

#[derive(Serialize)]
struct MatchReport {
    image: String,
    score: f32,
    inliers: usize,
}

/// A candidate checked, for the table.
struct Checked {
    query: usize,
    candidate: usize,
    score: f32,
    verification: Verification,
    accepted: bool,
}

/// Runs `spslam loops`.
pub fn run_loops(args: LoopsArgs) -> Result<()> {
    let paths = list_images(std::slice::from_ref(&args.images))?;
    let names: Vec<String> = paths
        .iter()
        .map(|p| {
            p.file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default()
        })
        .collect();
    // `spslam run`'s extractor with its defaults.
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let settings = ExtractorSettings {
        device: args.device,
        ..ExtractorSettings::default()
    };
    let config = settings.superpoint_config(DEFAULT_SUPERPOINT_LEVELS, cores);
    let codebook_path = args.codebook.clone().unwrap_or_else(default_codebook_path);
    let codebook = Codebook::load_for(&codebook_path, &config)
        .with_context(|| format!("cannot use the codebook {}", codebook_path.display()))?;
    let vlad = &codebook.vlad;
    let mut extractor =
        SuperPointExtractor::new(config).context("cannot create the SuperPoint extractor")?;

    let bar = ProgressBar::new(paths.len() as u64);
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} images, {elapsed} ({eta} left) {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let mut features: Vec<ImageFeatures> = Vec::with_capacity(paths.len());
    let mut globals: Vec<Option<Vec<f32>>> = Vec::with_capacity(paths.len());
    let mut database = KeyframeDatabase::<usize>::new(vlad.dim())?;
    let mut inserted = 0;
    let mut checked = Vec::new();
    let mut tracks = Tracks::default();
    let options = QueryOptions {
        n_best: args.candidates,
        ..QueryOptions::default()
    };
    for (i, path) in paths.iter().enumerate() {
        let (image_features, global) = describe(&mut extractor, vlad, path)?;
        let to_previous = match features.last() {
            Some(previous) => {
                verify(&image_features, previous)
                    .with_context(|| format!("cannot match {} with the previous image", names[i]))?
                    .inlier_pairs
            }
            None => Vec::new(),
        };
        tracks.add_image(i, image_features.points.len(), &to_previous);
        features.push(image_features);
        globals.push(global);
        let covisible_from = tracks.covisible_from(i, MIN_SHARED_TRACKS);
        // Images older than the recent window enter the database.
        while inserted + args.exclude_recent < i {
            if let Some(g) = &globals[inserted] {
                database.insert(inserted, g)?;
            }
            inserted += 1;
        }
        if let Some(g) = &globals[i] {
            // Neighbours in name order play the covisible keyframes.
            let neighbours = |j: usize| -> Vec<usize> {
                (1..=5)
                    .flat_map(|d| [j.checked_sub(d), Some(j + d)])
                    .flatten()
                    .collect()
            };
            let exclude: HashSet<usize> = (covisible_from..i).collect();
            for c in database.query(g, &exclude, neighbours, &options)? {
                let verification =
                    verify(&features[i], &features[c.keyframe]).with_context(|| {
                        format!("cannot verify {} against {}", names[i], names[c.keyframe])
                    })?;
                checked.push(Checked {
                    query: i,
                    candidate: c.keyframe,
                    score: c.score,
                    accepted: verification.inliers >= args.min_inliers,
                    verification,
                });
            }
        }
        bar.set_message(format!(
            "{} accepted",
            checked.iter().filter(|c| c.accepted).count()
        ));
        bar.inc(1);
    }
    bar.finish_and_clear();
    print_table(&checked, &names, &codebook_path, args.min_inliers);
    if let Some(out) = &args.json {
        write_json(out, &checked, &names)?;
    }
    Ok(())
}

/// Keypoint tracks through consecutive images: the stand-in for shared
/// map points.
#[derive(Default)]
struct Tracks {
    /// Per image, each keypoint's track id.
    ids: Vec<Vec<usize>>,
    /// Per track id, the first image it was seen in.
    first: Vec<usize>,
}

impl Tracks {
    /// Adds image `i` with `n` keypoints; `to_previous` pairs its keypoints
    /// with the previous image's (verified matches), which continue tracks.
    fn add_image(&mut self, i: usize, n: usize, to_previous: &[(usize, usize)]) {
        let mut ids = vec![usize::MAX; n];
        if let Some(previous) = self.ids.last() {
            for &(here, there) in to_previous {
                if let (Some(slot), Some(&id)) = (ids.get_mut(here), previous.get(there)) {
                    *slot = id;
                }
            }
        }
        for slot in ids.iter_mut().filter(|s| **s == usize::MAX) {
            *slot = self.first.len();
            self.first.push(i);
        }
        self.ids.push(ids);
    }

    /// The first earlier image sharing at least `min_shared` tracks with
    /// image `i` (tracks are contiguous, so every later image shares at
    /// least as many); `i` when none does.
    fn covisible_from(&self, i: usize, min_shared: usize) -> usize {
        let Some(ids) = self.ids.get(i) else {
            return i;
        };
        let mut starts: Vec<usize> = ids
            .iter()
            .map(|&t| self.first[t])
            .filter(|&f| f < i)
            .collect();
        if min_shared == 0 || starts.len() < min_shared {
            return i;
        }
        starts.sort_unstable();
        starts[min_shared - 1]
    }
}

/// One image's features and global descriptor (`None` without keypoints).
fn describe(
    extractor: &mut SuperPointExtractor,
    vlad: &spslam::place::Vlad,
    path: &Path,
) -> Result<(ImageFeatures, Option<Vec<f32>>)> {
    let image =
        GrayImage::load(path).with_context(|| format!("cannot read image {}", path.display()))?;
    let f = extractor
        .extract(image.view())
        .with_context(|| format!("extraction failed on {}", path.display()))?;
    let global = match vlad.compute_flat(&f.descriptors) {
        Ok(g) => Some(g),
        Err(PlaceError::NoDescriptors { .. }) => None,
        Err(e) => {
            return Err(e).with_context(|| format!("cannot describe {}", path.display()));
        }
    };
    let features = ImageFeatures {
        points: f.keypoints.iter().map(|k| (k.x, k.y)).collect(),
        descriptors: DescriptorSet::Float {
            dim: f.descriptor_len,
            data: f.descriptors,
        },
    };
    Ok((features, global))
}

fn print_table(checked: &[Checked], names: &[String], codebook: &Path, min_inliers: usize) {
    println!(
        "{} images, codebook {}; candidates verified (accepted: >= {min_inliers} inliers):",
        names.len(),
        codebook.display()
    );
    println!(
        "{:<28} {:<28} {:>6} {:>8} {:>8}  accepted",
        "image", "candidate", "score", "matches", "inliers"
    );
    for c in checked {
        println!(
            "{:<28} {:<28} {:>6.3} {:>8} {:>8}  {}",
            names[c.query],
            names[c.candidate],
            c.score,
            c.verification.matches,
            c.verification.inliers,
            if c.accepted { "yes" } else { "no" }
        );
    }
    println!(
        "{} accepted matches",
        checked.iter().filter(|c| c.accepted).count()
    );
}

fn write_json(out: &Path, checked: &[Checked], names: &[String]) -> Result<()> {
    let images = names
        .iter()
        .enumerate()
        .map(|(i, name)| ImageReport {
            image: name.clone(),
            matches: checked
                .iter()
                .filter(|c| c.query == i && c.accepted)
                .map(|c| MatchReport {
                    image: names[c.candidate].clone(),
                    score: c.score,
                    inliers: c.verification.inliers,
                })
                .collect(),
        })
        .collect();
    let text = serde_json::to_string_pretty(&Report { images })?;
    std::fs::write(out, text + "\n").with_context(|| format!("cannot write {}", out.display()))?;
    Ok(())
}
