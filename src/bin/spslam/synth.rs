//! `spslam synth`: writes a synthetic stereo/RGB-D sequence with exact
//! ground truth in the KITTI layout.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use spslam::dataset::synthetic::{
    write_sequence, Condition, SceneName, SyntheticConfig, SyntheticSequence, WriteOptions,
};

#[derive(clap::Args)]
pub struct SynthArgs {
    /// Output root: the sequence goes to OUT/sequences/NAME, the ground truth to OUT/poses/NAME.txt.
    #[arg(long)]
    out: PathBuf,
    /// Scene: loop (city block, back to the start), straight (street), wobbly (hand-held, corridor),
    /// highway (open road at 25 m/s, most texture 40-150 m away: stereo far points) or aliasing
    /// (a street passing two look-alike places whose walls stand at other distances: a false loop).
    #[arg(long, default_value = "loop")]
    scene: SceneName,
    /// Number of frames [default: one lap + 1 for loop, 300 for highway, 100 m past the second
    /// look-alike place for aliasing (300 at 10 m/s), 200 otherwise].
    #[arg(long)]
    frames: Option<usize>,
    /// Image size as WIDTHxHEIGHT.
    #[arg(long, default_value = "640x480", value_parser = parse_size)]
    size: (usize, usize),
    /// Seed of the textures, the shake and the noise.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Sequence name under sequences/.
    #[arg(long, default_value = "00")]
    sequence: String,
    /// Focal length in pixels [default: 400].
    #[arg(long)]
    focal: Option<f64>,
    /// Stereo baseline in metres [default: 0.5 outdoors, 0.12 for wobbly].
    #[arg(long)]
    baseline: Option<f64>,
    /// A stereo calibration error: every disparity reads this many pixels
    /// short (the right camera turned about its y axis; the written
    /// calibration still says the pair is parallel; the offset holds at the
    /// image centre and grows towards the sides). 0 = exact [default: 0].
    #[arg(long, value_name = "PX", allow_negative_numbers = true)]
    disparity_offset: Option<f64>,
    /// Frames per second [default: 10 outdoors, 20 for wobbly].
    #[arg(long)]
    fps: Option<f64>,
    /// Speed in m/s [default: 10 for loop, straight and aliasing, 25 for highway, 1.2 for wobbly].
    #[arg(long)]
    speed: Option<f64>,
    /// Gaussian pixel noise, standard deviation in gray levels [default: 1].
    #[arg(long)]
    noise: Option<f64>,
    /// Relative amplitude of the per-frame exposure change [default: 0.05].
    #[arg(long)]
    exposure: Option<f64>,
    /// Motion blur: sub-poses averaged per image (1 = off) [default: 1].
    #[arg(long)]
    blur: Option<usize>,
    /// A hard condition on the images (the ground truth stays exact):
    /// normal, light-ramp (gain 1 -> 0.4, gamma 1 -> 1.5 over the sequence),
    /// flicker (a random gain in [0.6, 1.4] per frame), dusk (from the
    /// second lap on, or the middle frame: dark, with shot and read noise),
    /// low-light (dark and noisy throughout), blackout (8 black frames
    /// in the middle: a kidnap), low-texture (façades of mostly bare
    /// plaster), repeated-texture (every façade the same grid of
    /// identical windows), turn-in-place (in the middle the camera stops
    /// and turns once round in 36 frames, up to 20° per frame) or
    /// jump-back (in the middle the camera is carried back a quarter of
    /// the path, to a place it has seen: a kidnap). The last two add
    /// their frames to --frames. A condition's own noise applies even
    /// with --clean.
    #[arg(long, default_value = "normal")]
    condition: Condition,
    /// Render without noise, exposure change or blur.
    #[arg(long)]
    clean: bool,
    /// Skip the depth maps and the TUM RGB-D lists.
    #[arg(long)]
    no_depth: bool,
    /// Replace an existing sequence folder.
    #[arg(long)]
    overwrite: bool,
    /// Rendering threads (0: all cores).
    #[arg(long, default_value_t = 0)]
    threads: usize,
}

fn parse_size(text: &str) -> std::result::Result<(usize, usize), String> {
    let parsed = text
        .split_once(['x', 'X'])
        .and_then(|(w, h)| Some((w.trim().parse().ok()?, h.trim().parse().ok()?)));
    parsed.ok_or_else(|| format!("`{text}` is not WIDTHxHEIGHT, e.g. 640x480"))
}

/// The config the arguments ask for: the scene's defaults, then each flag given.
fn config_from(args: &SynthArgs) -> SyntheticConfig {
    let mut config = SyntheticConfig::for_scene(args.scene);
    (config.width, config.height) = args.size;
    config.frames = args.frames;
    config.seed = args.seed;
    config.threads = args.threads;
    let set = |target: &mut f64, value: Option<f64>| {
        if let Some(v) = value {
            *target = v;
        }
    };
    set(&mut config.focal_length, args.focal);
    set(&mut config.baseline, args.baseline);
    set(&mut config.disparity_offset, args.disparity_offset);
    set(&mut config.fps, args.fps);
    set(&mut config.speed, args.speed);
    set(&mut config.pixel_noise, args.noise);
    set(&mut config.exposure_variation, args.exposure);
    if let Some(blur) = args.blur {
        config.blur_samples = blur;
    }
    if args.clean {
        config = config.noiseless();
    }
    config.condition = args.condition;
    config
}

pub fn run_synth(args: SynthArgs) -> Result<()> {
    if args.out.exists() && !args.out.is_dir() {
        bail!("--out {} exists and is not a folder", args.out.display());
    }
    let config = config_from(&args);
    let sequence = SyntheticSequence::new(config)?;
    let options = WriteOptions {
        sequence_name: args.sequence.clone(),
        with_depth: !args.no_depth,
        overwrite: args.overwrite,
    };
    let total = sequence.len();
    let every = (total / 20).max(1);
    let start = Instant::now();
    eprintln!(
        "[synth] scene {} : {total} frames of {}x{} into {}",
        args.scene,
        sequence.camera().width,
        sequence.camera().height,
        args.out.display()
    );
    let written = write_sequence(&sequence, &args.out, &options, &mut |done, total| {
        if done % every == 0 || done == total {
            let elapsed = start.elapsed().as_secs_f64();
            eprintln!(
                "[synth] {done}/{total} frames ({:.0}%), {:.1} s, {:.0} ms/frame",
                100.0 * done as f64 / total as f64,
                elapsed,
                1000.0 * elapsed / done as f64
            );
        }
    })
    .with_context(|| {
        format!(
            "writing the synthetic sequence under {}",
            args.out.display()
        )
    })?;
    println!("sequence:     {}", written.sequence_dir.display());
    println!("ground truth: {}", written.poses_path.display());
    println!("frames:       {}", written.frames);
    Ok(())
}
