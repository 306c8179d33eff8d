//! Writes a EuRoC sequence's stereo pairs undistorted and rectified (rows
//! aligned) with the rectifier `spslam run` uses, as `left/NAME.png` and
//! `right/NAME.png`, for tools that need rectified pairs
//! (`tools/stereo_same_row.py`).
//!
//! ```sh
//! cargo run --release --example rectify_euroc -- EUROC_DIR OUT_DIR [EVERY]
//! ```

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use opencv::core::Vector;
use opencv::imgcodecs;
use spslam::dataset::{EurocSequence, StereoRectifier};

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(input), Some(out)) = (args.first(), args.get(1)) else {
        bail!("usage: rectify_euroc EUROC_DIR OUT_DIR [EVERY]");
    };
    let every: usize = match args.get(2) {
        Some(text) => text
            .parse()
            .with_context(|| format!("EVERY `{text}` is not a count"))?,
        None => 1,
    };
    let sequence = EurocSequence::open(input)?;
    let rectifier = StereoRectifier::from_euroc(sequence.cam0(), sequence.cam1())?;
    let out = PathBuf::from(out);
    for side in ["left", "right"] {
        std::fs::create_dir_all(out.join(side))?;
    }
    let mut written = 0;
    for frame in sequence.frames().iter().step_by(every.max(1)) {
        let read = |path: &PathBuf| {
            imgcodecs::imread(path, imgcodecs::IMREAD_GRAYSCALE)
                .with_context(|| format!("cannot read {}", path.display()))
        };
        let pair = rectifier.rectify(&read(&frame.left)?, &read(&frame.right)?)?;
        let name = frame
            .left
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| written.to_string());
        for (side, image) in [("left", &pair.left), ("right", &pair.right)] {
            let path = out.join(side).join(format!("{name}.png"));
            if !imgcodecs::imwrite(&path, image, &Vector::new())? {
                bail!("cannot write {}", path.display());
            }
        }
        written += 1;
    }
    println!(
        "rectify_euroc: {written} pairs into {} (fx {:.1}, baseline {:.4} m, {}x{})",
        out.display(),
        rectifier.fx(),
        rectifier.baseline(),
        rectifier.image_size().0,
        rectifier.image_size().1
    );
    Ok(())
}
