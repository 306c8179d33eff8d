//! `spslam vocab`: place-recognition vocabularies. `spslam vocab train`
//! extracts descriptors from folders of images and trains a DBoW2
//! vocabulary tree on them (hierarchical k-means, TF-IDF weights), written
//! in the text format ORB-SLAM3's `loadFromTextFile` reads.

mod descriptors;
mod images;
mod train;

use std::path::PathBuf;

use anyhow::Result;
use spslam::features::{Device, Precision};

/// The arguments of `spslam vocab`.
#[derive(clap::Args)]
pub struct VocabArgs {
    #[command(subcommand)]
    command: VocabCommand,
}

#[derive(clap::Subcommand)]
enum VocabCommand {
    /// Train a vocabulary from folders of images and write it (DBoW2 text format).
    Train(TrainArgs),
}

/// `--format`: the file written.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum VocabFormat {
    // No doc comments on the variants: clap would turn them into a long
    // list of possible values in `--help`.
    Dbow2,
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
    /// L1-norm scoring, TF-IDF weighting).
    #[arg(long, value_enum, default_value_t = VocabFormat::Dbow2)]
    format: VocabFormat,
    /// Branching factor k, 2..=20 (ORB-SLAM3's loader accepts at most 20).
    #[arg(long, default_value_t = 10)]
    k: usize,
    /// Depth L, 1..=10 (ORB-SLAM3's loader accepts at most 10).
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
