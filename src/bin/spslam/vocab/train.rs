//! `spslam vocab train`: list the images, extract, cluster, write, report.

use std::path::Path;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use spslam::place::dbow2_text::{write_dbow2_text, Dbow2Element};
use spslam::place::{
    ClusterMetric, DescriptorRows, HammingBinary, L2Float, TreeParams, TreeProgress, TreeStage,
    VocabularyTree,
};

use super::descriptors::{extract_all, extractor, TrainingRows};
use super::images::{list_images, subsample};
use super::{check_out_dir, TrainArgs, VocabFormat};

/// dbow2's branching factor without `--k`.
const DEFAULT_DBOW2_K: usize = 10;

/// What clustering and writing produced, for the summary.
struct Trained {
    nodes: usize,
    words: usize,
    kmeans_runs: usize,
    kmeans_capped: usize,
    bytes: u64,
    cluster_s: f64,
    write_s: f64,
}

/// Runs `spslam vocab train`.
pub fn run_train(args: TrainArgs) -> Result<()> {
    if args.format == VocabFormat::Vlad {
        return super::vlad::run_train_vlad(args);
    }
    if args.pca.is_some() {
        bail!("--pca applies to --format vlad only");
    }
    let started = Instant::now();
    let k = args.k.unwrap_or(DEFAULT_DBOW2_K);
    let params = TreeParams {
        seed: args.seed,
        ..TreeParams::new(k, args.depth)
    };
    params.validate()?;
    check_out_dir(&args.out)?;
    let paths = subsample(list_images(&args.images)?, args.max_images)?;
    let mut extractor = extractor(&args)?;
    let set = extract_all(extractor.as_mut(), args.descriptors, &paths)?;
    let extract_s = started.elapsed().as_secs_f64();
    let (kind, trained) = match &set.rows {
        TrainingRows::Float(rows) => (
            format!("float[{}] (L2)", rows.row_len()),
            train(
                L2Float {
                    dim: rows.row_len(),
                },
                rows,
                &set.image_lengths,
                &params,
                &args,
            )?,
        ),
        TrainingRows::Binary(rows) => (
            format!("binary[{} bytes] (Hamming)", rows.row_len()),
            train(
                HammingBinary {
                    bytes: rows.row_len(),
                },
                rows,
                &set.image_lengths,
                &params,
                &args,
            )?,
        ),
    };
    println!(
        "wrote {} (DBoW2 text, k = {}, L = {})",
        args.out.display(),
        k,
        args.depth
    );
    println!("  extractor: {}", set.extractor);
    println!(
        "  images: {}, descriptors: {} {kind}",
        set.image_lengths.len(),
        set.len()
    );
    println!(
        "  tree: {} nodes, {} words; k-means on {} nodes ({} stopped by the iteration cap)",
        trained.nodes, trained.words, trained.kmeans_runs, trained.kmeans_capped
    );
    println!(
        "  file: {} bytes ({:.1} MiB)",
        trained.bytes,
        trained.bytes as f64 / (1024.0 * 1024.0)
    );
    println!(
        "  seconds: {:.1} in all (extraction {:.1}, clustering {:.1}, writing {:.1})",
        started.elapsed().as_secs_f64(),
        extract_s,
        trained.cluster_s,
        trained.write_s
    );
    Ok(())
}

/// Builds the tree over `rows` with a progress bar per level, and writes it.
fn train<M>(
    metric: M,
    rows: &DescriptorRows<M::Elem>,
    image_lengths: &[usize],
    params: &TreeParams,
    args: &TrainArgs,
) -> Result<Trained>
where
    M: ClusterMetric,
    M::Elem: Dbow2Element,
{
    let started = Instant::now();
    let mut bars = StageBars::new(params.depth);
    let outcome =
        VocabularyTree::build(metric, rows, image_lengths, params, &mut |p| bars.report(p));
    bars.finish();
    let outcome = outcome.context("cannot train the vocabulary")?;
    let cluster_s = started.elapsed().as_secs_f64();
    let started = Instant::now();
    let bytes = match args.format {
        VocabFormat::Dbow2 => write(&outcome.tree, &args.out)?,
        VocabFormat::Vlad => bail!("a VLAD codebook is not a vocabulary tree"),
    };
    Ok(Trained {
        nodes: outcome.tree.node_count(),
        words: outcome.tree.word_count(),
        kmeans_runs: outcome.kmeans_runs,
        kmeans_capped: outcome.kmeans_capped,
        bytes,
        cluster_s,
        write_s: started.elapsed().as_secs_f64(),
    })
}

fn write<M>(tree: &VocabularyTree<M>, out: &Path) -> Result<u64>
where
    M: ClusterMetric,
    M::Elem: Dbow2Element,
{
    let spinner = ProgressBar::new_spinner();
    spinner.set_message(format!("writing {}", out.display()));
    spinner.enable_steady_tick(std::time::Duration::from_millis(200));
    let bytes = write_dbow2_text(tree, out);
    spinner.finish_and_clear();
    Ok(bytes?)
}

/// One progress bar per training stage (each level, then the weights),
/// counting descriptors.
struct StageBars {
    depth: usize,
    current: Option<(TreeStage, ProgressBar)>,
}

impl StageBars {
    fn new(depth: usize) -> Self {
        Self {
            depth,
            current: None,
        }
    }

    fn report(&mut self, p: TreeProgress) {
        if self.current.as_ref().map(|(s, _)| *s) != Some(p.stage) {
            self.finish();
            let label = match p.stage {
                TreeStage::Level(l) => format!("level {l}/{}", self.depth),
                TreeStage::Weights => "weights".to_string(),
            };
            let bar = ProgressBar::new(p.total as u64);
            bar.set_style(
                ProgressStyle::with_template(
                    "{prefix:>10} {bar:40} {pos}/{len} descriptors, {elapsed} ({eta} left)",
                )
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
            );
            bar.set_prefix(label);
            self.current = Some((p.stage, bar));
        }
        if let Some((_, bar)) = &self.current {
            bar.set_position(p.done as u64);
        }
    }

    fn finish(&mut self) {
        if let Some((_, bar)) = self.current.take() {
            bar.finish();
        }
    }
}
