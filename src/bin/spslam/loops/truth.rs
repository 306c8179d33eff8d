//! The ground truth of `spslam loops --dataset`: each frame's camera pose
//! and depth, and from them which earlier frames truly show the query's
//! place (`spslam::eval::place_recognition`).
//!
//! Depth comes, in order of preference, from the synthetic scene itself
//! (`spslam synth` output: its `synthetic.json` rebuilds the scene, and
//! rays are cast with no range limit, where the 16-bit depth images stop
//! at 13.1 m), from the sequence's depth images, or from one nominal depth
//! (`--truth-depth`).

use std::path::Path;

use anyhow::{bail, Context, Result};
use nalgebra::{Isometry3, Point3, Vector3};
use spslam::camera::DepthImage;
use spslam::dataset::synthetic::{SyntheticConfig, SyntheticSequence};
use spslam::eval::place_recognition::precision_recall::DIFFERENT_PLACE_OVERLAP;
use spslam::eval::place_recognition::{view_overlap, CandidateTruth, OverlapCamera, SceneDepth};
use spslam::eval::Trajectory;

use crate::run::source::{InputFrame, Source};

/// Pixels between the depth samples kept per frame.
const DEPTH_SAMPLE_STEP: usize = 4;
/// Pixels between the rays cast into a synthetic scene.
const RAY_STEP: usize = 16;
/// Largest time difference (s) between a frame and its ground-truth pose
/// when they are paired by time (TUM layout).
const MAX_POSE_TIME_DIFFERENCE: f64 = 0.02;

/// The ground truth gathered as frames are read.
pub struct FrameTruth {
    camera: OverlapCamera,
    /// Per frame, the camera-to-world pose (`None`: no pose within
    /// [`MAX_POSE_TIME_DIFFERENCE`]).
    poses: Vec<Option<Isometry3<f64>>>,
    /// Per frame read so far, its depth.
    depths: Vec<SceneDepth>,
    /// The depth used where a frame has no depth image.
    nominal_depth: Option<f64>,
    /// The synthetic scene the sequence was rendered from, if it was.
    scene: Option<SyntheticSequence>,
}

/// The scene of a `spslam synth` sequence folder (its `synthetic.json`),
/// or `None` for other folders.
pub fn synthetic_scene(folder: &Path) -> Result<Option<SyntheticSequence>> {
    let path = folder.join("synthetic.json");
    if !path.is_file() {
        return Ok(None);
    }
    let text = std::fs::read_to_string(&path)
        .with_context(|| format!("cannot read {}", path.display()))?;
    let config: SyntheticConfig = serde_json::from_str(&text)
        .with_context(|| format!("{} is not a spslam synth configuration", path.display()))?;
    let sequence = SyntheticSequence::new(config)
        .with_context(|| format!("cannot rebuild the scene of {}", path.display()))?;
    Ok(Some(sequence))
}

impl FrameTruth {
    /// The poses of `frames` from the dataset's ground truth; `nominal_depth`
    /// stands in for depth images where the sequence has none.
    pub fn new(
        source: &Source,
        frames: &[InputFrame],
        camera: OverlapCamera,
        nominal_depth: Option<f64>,
        scene: Option<SyntheticSequence>,
    ) -> Result<Self> {
        if matches!(source, Source::Euroc(_)) {
            bail!("EuRoC's ground truth is the body (IMU) pose, not the camera's: `spslam loops --dataset euroc:` cannot judge overlap (use --images)");
        }
        let has_depth = frames
            .iter()
            .all(|f| f.depth.is_some() || f.right.is_some())
            || scene.is_some();
        if !has_depth && nominal_depth.is_none() {
            bail!("this sequence has no depth images: give --truth-depth METRES, a typical distance to the scene, to judge which views overlap");
        }
        let Some(gt) = source.ground_truth(frames.len())? else {
            bail!("the dataset has no ground truth, which `spslam loops --dataset` needs (use --images without it)");
        };
        let poses = if source.is_kitti() {
            (0..frames.len())
                .map(|i| gt.poses.get(i).copied())
                .collect()
        } else {
            frames
                .iter()
                .map(|f| nearest_pose(&gt, f.timestamp))
                .collect()
        };
        Ok(Self {
            camera,
            poses,
            depths: Vec::with_capacity(frames.len()),
            nominal_depth,
            scene,
        })
    }

    /// Records the next frame's depth: cast into the synthetic scene, from
    /// its depth image, or the nominal depth.
    pub fn add_frame(&mut self, depth: Option<&DepthImage>) {
        let index = self.depths.len();
        let sampled = match (&self.scene, depth, self.nominal_depth) {
            (Some(scene), _, _) => cast_depth(scene, index, &self.camera),
            (None, Some(d), _) => {
                SceneDepth::sample(d.as_slice(), d.width(), d.height(), DEPTH_SAMPLE_STEP)
            }
            (None, None, Some(nominal)) => SceneDepth::Nominal(nominal),
            (None, None, None) => SceneDepth::Nominal(0.0),
        };
        self.depths.push(sampled);
    }

    /// How much of frame `query`'s view frame `candidate` sees; `None`
    /// without a pose for either.
    pub fn overlap(&self, query: usize, candidate: usize) -> Option<f64> {
        let q = self.poses.get(query).copied().flatten()?;
        let c = self.poses.get(candidate).copied().flatten()?;
        Some(view_overlap(
            &self.camera,
            &q,
            self.depths.get(query)?,
            &c,
            self.depths.get(candidate)?,
        ))
    }

    /// Whether frame `query` revisits a place: one of `searchable` (earlier
    /// frames) shows its view, and the camera looked away in between (a
    /// later frame, before the query, overlaps the query's view by less than
    /// [`DIFFERENT_PLACE_OVERLAP`]). Without the second condition, every
    /// frame of a forward drive would "revisit" the frames behind it, which
    /// saw its view from further away: those are one pass, not a loop.
    pub fn revisits(&self, query: usize, searchable: &[usize]) -> bool {
        // Each earlier frame's overlap with the query, computed once.
        let overlaps: Vec<Option<f64>> = (0..query).map(|k| self.overlap(query, k)).collect();
        let last_away = overlaps
            .iter()
            .rposition(|o| o.is_some_and(|o| o < DIFFERENT_PLACE_OVERLAP));
        let Some(last_away) = last_away else {
            return false;
        };
        searchable.iter().any(|&j| {
            j < last_away
                && overlaps[j]
                    .is_some_and(|o| CandidateTruth::from_overlap(o) == CandidateTruth::Same)
        })
    }
}

/// Frame `index`'s depth in the synthetic scene, every [`RAY_STEP`] pixels
/// (0 where a ray meets only the sky).
fn cast_depth(scene: &SyntheticSequence, index: usize, camera: &OverlapCamera) -> SceneDepth {
    let pose = scene.pose(index);
    let eye = Point3::from(pose.translation.vector);
    let cols = camera.width.div_ceil(RAY_STEP);
    let rows = camera.height.div_ceil(RAY_STEP);
    let mut depth = Vec::with_capacity(cols * rows);
    for r in 0..rows {
        for c in 0..cols {
            let (u, v) = ((c * RAY_STEP) as f64, (r * RAY_STEP) as f64);
            let ray = Vector3::new(
                (u - camera.cx) / camera.fx,
                (v - camera.cy) / camera.fy,
                1.0,
            );
            // Along a ray with unit z in the camera, t is the depth.
            let direction = pose.rotation * ray;
            let z = scene
                .world()
                .cast(&eye, &direction)
                .map_or(0.0, |hit| hit.t);
            depth.push(z as f32);
        }
    }
    SceneDepth::Sampled {
        step: RAY_STEP,
        cols,
        rows,
        depth,
    }
}

/// The ground-truth pose nearest in time to `t`, within the tolerance.
fn nearest_pose(gt: &Trajectory, t: f64) -> Option<Isometry3<f64>> {
    let i = gt.timestamps.partition_point(|&s| s < t);
    [i.checked_sub(1), Some(i)]
        .into_iter()
        .flatten()
        .filter(|&k| k < gt.len())
        .min_by(|&a, &b| {
            (gt.timestamps[a] - t)
                .abs()
                .total_cmp(&(gt.timestamps[b] - t).abs())
        })
        .filter(|&k| (gt.timestamps[k] - t).abs() <= MAX_POSE_TIME_DIFFERENCE)
        .map(|k| gt.poses[k])
}

#[cfg(test)]
mod tests {
    use super::*;
    use spslam::dataset::synthetic::render_view;

    /// The depth cast into the scene is the rendered depth map's wherever
    /// the renderer has one (silhouette pixels aside), and goes on beyond
    /// it: rays meeting façades over 13.1 m away, the 16-bit files' limit.
    #[test]
    fn cast_depth_agrees_with_the_rendered_depth_and_reaches_further() {
        let config = SyntheticConfig {
            width: 320,
            height: 240,
            focal_length: 200.0,
            ..SyntheticConfig::default()
        };
        let scene = SyntheticSequence::new(config).expect("scene");
        let camera = OverlapCamera {
            fx: scene.camera().fx,
            fy: scene.camera().fy,
            cx: scene.camera().cx,
            cy: scene.camera().cy,
            width: 320,
            height: 240,
        };
        let index = 30;
        let view = render_view(scene.world(), scene.camera(), &scene.pose(index), true, 1);
        let SceneDepth::Sampled { cols, depth, .. } = cast_depth(&scene, index, &camera) else {
            panic!("sampled depth expected");
        };
        let (mut compared, mut agree, mut far) = (0, 0, 0);
        for (k, &cast) in depth.iter().enumerate() {
            let (u, v) = ((k % cols) * RAY_STEP, (k / cols) * RAY_STEP);
            let rendered = view.depth[v * 320 + u];
            if rendered > 0.0 {
                compared += 1;
                if (cast - rendered).abs() <= 0.01 * rendered {
                    agree += 1;
                }
            }
            if cast > 13.2 {
                far += 1;
            }
        }
        assert!(compared > 100, "{compared} samples compared");
        assert!(
            agree as f64 >= 0.95 * compared as f64,
            "{agree} of {compared} agree"
        );
        assert!(far > 0, "no sample beyond 13.2 m");
    }
}
