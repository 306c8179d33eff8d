//! `spslam vocab train --format vlad`: the VLAD codebook. The same image
//! listing and extraction as the DBoW2 vocabulary, one flat k-means (the
//! library's, with [`L2Float`]) over every SuperPoint descriptor, optional PCA
//! whitening fitted on the training images' VLADs, written with the hash of
//! the extractor settings.

use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use indicatif::ProgressBar;
use spslam::features::SuperPointExtractor;
use spslam::place::{
    extractor_settings_hash, kmeans, Codebook, DescriptorRows, KMeansOptions, L2Float, SeededRng,
    Vlad, Whitening, DEFAULT_K,
};

use super::descriptors::{extract_all, run_superpoint_config, TrainingRows};
use super::images::{list_images, subsample};
use super::{check_out_dir, DescriptorChoice, TrainArgs};

/// The `eps` of the whitening's `1 / sqrt(λ + eps)`: small against the
/// eigenvalues of unit-norm VLADs (the largest are around 1e-2).
const WHITENING_EPS: f64 = 1e-6;

/// Runs `spslam vocab train --format vlad`.
pub fn run_train_vlad(args: TrainArgs) -> Result<()> {
    let started = Instant::now();
    let k = args.k.unwrap_or(DEFAULT_K);
    if k == 0 {
        bail!("--k must be at least 1");
    }
    if args.descriptors != DescriptorChoice::Float {
        bail!("--format vlad is trained on SuperPoint's float descriptors (--descriptors float)");
    }
    check_out_dir(&args.out)?;
    let paths = subsample(list_images(&args.images)?, args.max_images)?;
    if let Some(pca) = args.pca {
        if pca == 0 || pca >= paths.len() {
            bail!(
                "--pca {pca}: the whitening size must be between 1 and the number of training images − 1 ({})",
                paths.len().saturating_sub(1)
            );
        }
    }
    let config = run_superpoint_config(&args)?;
    let settings_hash = extractor_settings_hash(&config);
    let mut extractor =
        SuperPointExtractor::new(config).context("cannot create the SuperPoint extractor")?;
    let set = extract_all(&mut extractor, DescriptorChoice::Float, &paths)?;
    let TrainingRows::Float(rows) = &set.rows else {
        bail!("the extractor gave binary descriptors; a VLAD codebook needs float ones");
    };
    let extract_s = started.elapsed().as_secs_f64();

    let clustering = Instant::now();
    let spinner = ProgressBar::new_spinner();
    spinner.set_message(format!("k-means, k = {k}, on {} descriptors", rows.len()));
    spinner.enable_steady_tick(Duration::from_millis(200));
    let metric = L2Float {
        dim: rows.row_len(),
    };
    let result = kmeans(
        &metric,
        rows,
        &KMeansOptions::new(k),
        &mut SeededRng::new(args.seed),
    );
    spinner.finish_and_clear();
    let result = result.context("cannot train the codebook")?;
    if result.centres.len() < k {
        bail!(
            "the {} training descriptors hold only {} distinct values; k = {k} needs more",
            rows.len(),
            result.centres.len()
        );
    }
    let mut vlad = Vlad::new(result.centres)?;
    let cluster_s = clustering.elapsed().as_secs_f64();

    let whitening_started = Instant::now();
    if let Some(pca) = args.pca {
        let mut training = DescriptorRows::new(vlad.raw_dim())?;
        let mut offset = 0;
        for &n in &set.image_lengths {
            let image = &rows.as_flat()[offset * rows.row_len()..(offset + n) * rows.row_len()];
            offset += n;
            if n > 0 {
                training.push_row(&vlad.raw(image)?)?;
            }
        }
        let whitening = Whitening::fit(&training, pca, WHITENING_EPS)
            .context("cannot fit the PCA whitening")?;
        vlad = vlad.with_whitening(whitening)?;
    }
    let whitening_s = whitening_started.elapsed().as_secs_f64();

    let codebook = Codebook {
        vlad,
        settings_hash,
    };
    let bytes = codebook.save(&args.out)?;
    println!(
        "wrote {} (VLAD codebook, k = {k}, {} values per descriptor{})",
        args.out.display(),
        rows.row_len(),
        args.pca
            .map(|p| format!(", PCA-whitened to {p}"))
            .unwrap_or_default()
    );
    println!("  extractor: {}", set.extractor);
    println!("  extractor settings hash: {settings_hash:#018x}");
    println!(
        "  images: {}, descriptors: {}",
        set.image_lengths.len(),
        rows.len()
    );
    println!(
        "  k-means: {} rounds{}",
        result.iterations,
        if result.converged {
            ", converged"
        } else {
            " (stopped by the iteration cap)"
        }
    );
    println!("  file: {bytes} bytes");
    println!(
        "  seconds: {:.1} in all (extraction {:.1}, clustering {:.1}, whitening {:.1})",
        started.elapsed().as_secs_f64(),
        extract_s,
        cluster_s,
        whitening_s
    );
    Ok(())
}
