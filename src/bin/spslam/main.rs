//! The `spslam` command line: one module per subcommand.

mod eval;
mod evaluate;
mod extract;
mod loops;
mod map;
mod plot_plane;
mod run;
mod synth;
mod vocab;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "spslam",
    version,
    about = "SuperPoint-SLAM3 in Rust: SuperPoint + ANMS features and SLAM"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Extract SuperPoint + ANMS keypoints and descriptors from images.
    Extract(extract::ExtractArgs),
    /// Evaluate an estimated trajectory against ground truth (KITTI metric, ATE, RPE).
    Eval(eval::EvalArgs),
    /// The evaluation suite: run the cases of a case list (several at a
    /// time, skipping finished ones) and write the summary tables.
    Evaluate(evaluate::EvaluateArgs),
    /// Run stereo SLAM over a sequence and write its trajectory and report.
    Run(run::RunArgs),
    /// Write a synthetic stereo/RGB-D sequence with exact ground truth (KITTI layout).
    Synth(synth::SynthArgs),
    /// Place-recognition vocabularies: `spslam vocab train` trains a DBoW2
    /// vocabulary or a VLAD codebook.
    Vocab(vocab::VocabArgs),
    /// Find revisited places in a folder of images (VLAD + fundamental-matrix RANSAC).
    Loops(loops::LoopsArgs),
    /// Map files: `spslam map info FILE` tells what one holds.
    Map(map::MapArgs),
}

fn main() -> std::process::ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "warn".into()),
        )
        .with_writer(std::io::stderr)
        .init();
    // Usage errors exit with 1, like every other failure to start (clap's
    // own code, 2, is `spslam run`'s code for an incomplete run).
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            // Nothing more can be reported when printing the usage fails.
            let _ = e.print();
            return if e.use_stderr() {
                std::process::ExitCode::FAILURE
            } else {
                std::process::ExitCode::SUCCESS
            };
        }
    };
    let success = |()| std::process::ExitCode::SUCCESS;
    // `spslam run` picks its own code (0 complete, 2 incomplete); an error
    // from any subcommand is 1.
    let result = match cli.command {
        Command::Extract(args) => extract::run_extract(args).map(success),
        Command::Eval(args) => eval::run_eval(args).map(success),
        Command::Evaluate(args) => evaluate::run_evaluate(args).map(success),
        Command::Synth(args) => synth::run_synth(args).map(success),
        Command::Run(args) => run::run_slam(args),
        Command::Vocab(args) => vocab::run_vocab(args).map(success),
        Command::Loops(args) => loops::run_loops(args).map(success),
        Command::Map(args) => map::run_map(args).map(success),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
