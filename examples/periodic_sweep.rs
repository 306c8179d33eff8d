//! Sweeps the periodic-artefact filter's settings over cached network outputs
//! of the KITTI 06 and EuRoC excerpts, and prints the dominant sub-cell phase
//! fraction and keypoint counts for each. Usage:
//! `cargo run --release --example periodic_sweep [DATA_DIR]`.

use std::path::{Path, PathBuf};

use ndarray::{Array2, Array4};
use spslam::features::anms;
use spslam::features::model::{fill_padded_input, SuperPointModel};
use spslam::features::nms::{nms_candidates, ValidRegion};
use spslam::features::periodic::{dominant_phase_fraction, local_contrast, LatticeMask};
use spslam::features::{default_model_path, AnmsMethod, GrayImage};

fn frames(data: &Path) -> Vec<(String, PathBuf)> {
    let mut out = vec![];
    let kitti = data.join("kitti/sequences/06/image_0");
    for i in (0..51).step_by(2) {
        out.push(("kitti".to_string(), kitti.join(format!("{i:06}.png"))));
    }
    let euroc = data.join("euroc/V1_01_easy_first95/mav0/cam0/data");
    let mut names: Vec<_> = std::fs::read_dir(&euroc)
        .map(|d| d.filter_map(|e| e.ok()).map(|e| e.path()).collect())
        .unwrap_or_default();
    names.sort();
    for p in names.into_iter().step_by(4) {
        out.push(("euroc".to_string(), p));
    }
    out
}

fn main() -> anyhow::Result<()> {
    let data = std::env::args()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("../shared/data"));
    let mut model = SuperPointModel::load(
        &default_model_path(),
        None,
        0,
        spslam::features::Device::Cpu,
    )?;
    let mut cached = vec![];
    for (set, path) in frames(&data) {
        let img = GrayImage::load(&path)?;
        let mut buffer = Vec::new();
        let (pw, ph) = fill_padded_input(img.view(), &mut buffer);
        let input = Array4::from_shape_vec((1, 1, ph, pw), buffer)?;
        let scores: Array2<f32> = model.run(input.view(), |s, _| s.to_owned())?;
        cached.push((set, img, scores));
    }
    eprintln!("cached {} frames", cached.len());
    let thr = 0.005f32;
    for mode in ["none", "cell1", "cell2", "cell3"] {
        for contrast in [0.0f32, 5.0, 6.0, 8.0] {
            let mut stats =
                std::collections::BTreeMap::<String, (Vec<(f32, f32)>, usize, usize)>::new();
            for (set, img, scores) in &cached {
                let (w, h) = (img.width(), img.height());
                let region = ValidRegion {
                    width: w,
                    height: h,
                    border: 8,
                };
                let cands = match mode {
                    "none" => nms_candidates(scores.view(), |_, _, s| s, thr, 4, region),
                    m if m.starts_with("cell") => {
                        let support: usize = m[4..].parse()?;
                        let mask =
                            LatticeMask::estimate(scores.view(), w, h, thr, support, &mut vec![]);
                        nms_candidates(
                            scores.view(),
                            |x, y, s| if mask.is_suppressed(x, y) { 0.0 } else { s },
                            thr,
                            4,
                            region,
                        )
                    }
                    _ => anyhow::bail!("unknown mode {mode}"),
                };
                let cands: Vec<_> = cands
                    .into_iter()
                    .filter(|c| {
                        contrast <= 0.0
                            || local_contrast(img.view(), c.x as usize, c.y as usize, 4) >= contrast
                    })
                    .collect();
                let sel = anms::select(AnmsMethod::Kdtree, &cands, 1000, w, h);
                let e = stats.entry(set.clone()).or_default();
                e.0.extend(sel.iter().map(|&i| (cands[i].x, cands[i].y)));
                e.1 += 1;
                e.2 += cands.len();
            }
            let line: Vec<String> = stats
                .iter()
                .map(|(set, (pts, n, nc))| {
                    let (f, p) = dominant_phase_fraction(pts.iter().copied());
                    format!(
                        "{set}: phase {p:?} {:.1}% kps/frame {:.0} cands/frame {:.0}",
                        100.0 * f,
                        pts.len() as f64 / *n as f64,
                        *nc as f64 / *n as f64
                    )
                })
                .collect();
            println!("{mode:6} contrast {contrast:3}: {}", line.join(" | "));
        }
    }
    Ok(())
}
