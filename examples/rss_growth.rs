//! Checks that repeated extractions do not leak: runs N consecutive
//! extractions of one frame with a single extractor and prints the resident
//! set size (VmRSS) after extraction 10, 100, 500 and N. Exits with status 1
//! when RSS grows by more than 16 MiB between extraction 10 and N. Usage:
//! `cargo run --release --example rss_growth [N=1000] [IMAGE]`
//! (IMAGE defaults to KITTI 06 frame 0 under `SPSLAM_DATA` or `../shared/data`).

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use spslam::features::{ExtractorConfig, GrayImage, SuperPointExtractor};

/// Largest accepted growth from extraction 10 to N, in MiB.
const MAX_GROWTH_MIB: f64 = 16.0;

/// VmRSS of this process in KiB, from `/proc/self/status`.
fn rss_kib() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmRSS:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

fn default_image() -> PathBuf {
    let data = std::env::var_os("SPSLAM_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data"));
    data.join("kitti/sequences/06/image_0/000000.png")
}

fn main() -> ExitCode {
    let mut args = std::env::args().skip(1);
    let n: usize = match args.next() {
        None => 1000,
        Some(s) => match s.parse() {
            Ok(n) if n >= 10 => n,
            _ => {
                eprintln!("rss_growth: N must be an integer >= 10, got `{s}`");
                return ExitCode::from(2);
            }
        },
    };
    let path = args.next().map(PathBuf::from).unwrap_or_else(default_image);
    let image = match GrayImage::load(&path) {
        Ok(img) => img,
        Err(e) => {
            eprintln!("rss_growth: cannot load image {}: {e}", path.display());
            return ExitCode::from(2);
        }
    };
    let mut extractor = match SuperPointExtractor::new(ExtractorConfig::default()) {
        Ok(x) => x,
        Err(e) => {
            eprintln!("rss_growth: cannot create the extractor: {e}");
            return ExitCode::from(2);
        }
    };
    let Some(start_rss) = rss_kib() else {
        eprintln!("rss_growth: cannot read VmRSS from /proc/self/status");
        return ExitCode::from(2);
    };
    println!(
        "rss_growth: {n} extractions of {} ({}x{}); VmRSS after model load: {:.1} MiB",
        path.display(),
        image.width(),
        image.height(),
        start_rss as f64 / 1024.0
    );

    let checkpoints = [10, 100, 500, n];
    let mut rss_at_10 = None;
    let mut last_rss = start_rss;
    let t0 = Instant::now();
    for i in 1..=n {
        let keypoints = match extractor.extract(image.view()) {
            Ok(f) => f.len(),
            Err(e) => {
                eprintln!("rss_growth: extraction {i} failed: {e}");
                return ExitCode::from(2);
            }
        };
        if checkpoints.contains(&i) {
            last_rss = rss_kib().unwrap_or(0);
            if i == 10 {
                rss_at_10 = Some(last_rss);
            }
            println!(
                "after extraction {i:>5}: VmRSS {:>8.1} MiB  ({keypoints} keypoints, {:.1} ms/extraction so far)",
                last_rss as f64 / 1024.0,
                t0.elapsed().as_secs_f64() * 1e3 / i as f64
            );
        }
    }
    let base = rss_at_10.unwrap_or(start_rss);
    let growth_mib = (last_rss as f64 - base as f64) / 1024.0;
    println!("growth from extraction 10 to {n}: {growth_mib:+.2} MiB (limit {MAX_GROWTH_MIB} MiB)");
    if growth_mib > MAX_GROWTH_MIB {
        eprintln!(
            "rss_growth: FAIL: resident set grew by {growth_mib:.2} MiB > {MAX_GROWTH_MIB} MiB"
        );
        return ExitCode::FAILURE;
    }
    println!("rss_growth: OK");
    ExitCode::SUCCESS
}
