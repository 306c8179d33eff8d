//! `spslam map info FILE`: what a map file holds, without loading it into
//! a system (the header is checked, the maps' consistency is not).

use std::path::PathBuf;

use anyhow::{Context, Result};
use spslam::storage::{peek, StoredDescriptors, FORMAT_VERSION, HEADER_LEN};

/// `spslam map …`.
#[derive(clap::Args)]
pub struct MapArgs {
    #[command(subcommand)]
    command: MapCommand,
}

#[derive(clap::Subcommand)]
enum MapCommand {
    /// Version, sizes, counts, hashes and the settings a map file was built with.
    Info {
        /// The map file (`spslam run --save-map`).
        file: PathBuf,
    },
}

/// Bytes of a descriptor block's payload.
fn block_bytes(block: &StoredDescriptors) -> usize {
    match block {
        StoredDescriptors::F32 { bytes, .. }
        | StoredDescriptors::F16 { bytes, .. }
        | StoredDescriptors::Binary { bytes } => bytes.len(),
        StoredDescriptors::U8 { scales, bytes, .. } => scales.len() + bytes.len(),
    }
}

/// Runs `spslam map`.
pub fn run_map(args: MapArgs) -> Result<()> {
    let MapCommand::Info { file } = args.command;
    let bytes = std::fs::read(&file).with_context(|| format!("cannot read {}", file.display()))?;
    let atlas = peek(&file, &bytes)?;
    let meta = &atlas.meta;
    let rig = &meta.rig;
    let mut text = format!(
        "{}: spslam map file, format version {FORMAT_VERSION}, {} bytes ({} header, CRC-32 checked)\n\
         written by spslam {}\n\
         extractor {}, descriptors stored as {}\n\
         extractor settings: {}\n\
         model hash: {}\n\
         codebook hash: {}\n\
         camera: {}, fx {:.3} fy {:.3} cx {:.3} cy {:.3}, baseline {:.4} m, {}x{} px, {:.1} fps\n\
         active map: {}\n",
        file.display(),
        bytes.len(),
        HEADER_LEN,
        meta.spslam_version,
        meta.extractor,
        meta.precision.name(),
        if meta.extractor_settings.is_empty() {
            "(not recorded)"
        } else {
            &meta.extractor_settings
        },
        meta.model_hash.as_deref().unwrap_or("(none)"),
        meta.codebook_hash.as_deref().unwrap_or("(none)"),
        rig.sensor,
        rig.fx,
        rig.fy,
        rig.cx,
        rig.cy,
        rig.baseline,
        rig.width,
        rig.height,
        rig.fps,
        meta.active_map,
    );
    for m in &atlas.maps {
        let keyframes = m.parts.keyframes.len();
        let keypoints: usize = m.parts.keyframes.iter().map(|k| k.keypoints.len()).sum();
        let descriptor_bytes: usize = m
            .keyframe_descriptors
            .iter()
            .map(block_bytes)
            .sum::<usize>()
            + block_bytes(&m.point_descriptors);
        let loop_edges: usize = m
            .parts
            .keyframes
            .iter()
            .filter_map(|k| k.graph.as_ref())
            .map(|g| g.loop_edges.len())
            .sum::<usize>()
            / 2;
        text.push_str(&format!(
            "map {}: first frame {}, {} keyframes ({} keypoints), {} map points, {} culled keyframes, {} loop edges, descriptors {:.1} MB{}\n",
            m.index,
            m.first_frame,
            keyframes,
            keypoints,
            m.parts.points.len(),
            m.parts.culled.len(),
            loop_edges,
            descriptor_bytes as f64 / 1e6,
            m.merged_into
                .map(|i| format!(", merged into map {i}"))
                .unwrap_or_default()
        ));
    }
    let keyframes: usize = atlas.maps.iter().map(|m| m.parts.keyframes.len()).sum();
    if keyframes > 0 {
        text.push_str(&format!(
            "{:.3} MB per keyframe\n",
            bytes.len() as f64 / keyframes as f64 / 1e6
        ));
    }
    print!("{text}");
    Ok(())
}
