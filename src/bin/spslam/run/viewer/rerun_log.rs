//! The logging thread: rerun archetypes from the feed's copies.
//!
//! Entities (`world` is the first camera's frame, x right, y down, z forward):
//! `world/camera` (the current pose; `image` below it with the frame and its
//! `keypoints`, tracked green and untracked red), `world/trajectory/estimate`
//! and `world/trajectory/ground_truth`, `world/maps/<m>/points` (coloured
//! by map) and `world/maps/<m>/keyframes/<id>` (frusta), `world/edges`
//! (accepted loops and merges); on the `frame` and `time` timelines, the
//! scalars `tracking/inliers`, `tracking/keyframe` and
//! `timings/{extraction,tracking,mapping}_ms`.

use std::collections::BTreeMap;
use std::sync::mpsc::Receiver;

use anyhow::{Context, Result};
use rerun::{RecordingStream, RecordingStreamBuilder};
use spslam::optim::Se3;

use spslam::camera::CameraRig;

use super::{FrameMessage, MapsMessage, ViewerMessage, ViewerTarget};

/// Distance of a keyframe frustum's image plane, metres.
const FRUSTUM_DEPTH_M: f32 = 0.3;
/// The frames' JPEG quality.
const JPEG_QUALITY: i32 = 80;
/// A keyframe is logged again when it moved more than this (metres).
const KEYFRAME_MOVED_M: f64 = 0.01;

const TRACKED: [u8; 4] = [60, 200, 80, 255];
const UNTRACKED: [u8; 4] = [220, 60, 60, 255];
const MAP_COLOURS: [[u8; 4]; 6] = [
    [70, 130, 230, 255],
    [240, 160, 40, 255],
    [150, 90, 210, 255],
    [40, 180, 170, 255],
    [200, 80, 140, 255],
    [130, 130, 130, 255],
];

/// Opens the recording.
pub fn open(target: &ViewerTarget, title: &str) -> Result<RecordingStream> {
    let builder = RecordingStreamBuilder::new("spslam").recording_name(title.to_string());
    Ok(match target {
        ViewerTarget::File(path) => builder
            .save(path)
            .with_context(|| format!("cannot write the recording {}", path.display()))?,
        ViewerTarget::Connect(url) => builder
            .connect_grpc_opts(url.clone())
            .with_context(|| format!("cannot stream to the viewer at {url}"))?,
        ViewerTarget::Spawn { executable } => {
            let options = rerun::SpawnOptions {
                executable_path: Some(executable.display().to_string()),
                ..Default::default()
            };
            builder.spawn_opts(&options).with_context(|| {
                format!(
                    "cannot start the viewer {} (`make setup-viewer` installs it)",
                    executable.display()
                )
            })?
        }
    })
}

/// The frame as a JPEG (quality [`JPEG_QUALITY`]): a tenth of the raw
/// bytes, so that the recording's own threads stay light next to SLAM's.
fn jpeg(gray: &[u8], width: usize, height: usize) -> Option<Vec<u8>> {
    use opencv::core::{Mat, MatTraitConst, Vector, VectorToVec};
    if gray.len() != width * height || width == 0 {
        return None;
    }
    let flat = Mat::from_slice(gray).ok()?;
    let image = flat.reshape(1, height as i32).ok()?;
    let mut bytes = Vector::<u8>::new();
    let params = Vector::from_slice(&[opencv::imgcodecs::IMWRITE_JPEG_QUALITY, JPEG_QUALITY]);
    opencv::imgcodecs::imencode(".jpg", &image, &mut bytes, &params).ok()?;
    Some(bytes.to_vec())
}

fn colour([r, g, b, a]: [u8; 4]) -> rerun::Color {
    rerun::Color::from_unmultiplied_rgba(r, g, b, a)
}

fn translation_rotation(pose: &Se3) -> ([f32; 3], rerun::Quaternion) {
    let iso = pose.to_isometry();
    let t = iso.translation.vector;
    let q = iso.rotation.coords;
    (
        [t.x as f32, t.y as f32, t.z as f32],
        rerun::Quaternion::from_xyzw([q.x as f32, q.y as f32, q.z as f32, q.w as f32]),
    )
}

fn transform(pose: &Se3) -> rerun::Transform3D {
    let (translation, rotation) = translation_rotation(pose);
    rerun::Transform3D::from_translation_rotation(translation, rotation)
}

fn pinhole(rig: &CameraRig) -> rerun::Pinhole {
    let c = &rig.camera;
    rerun::Pinhole::from_focal_length_and_resolution(
        [c.fx as f32, c.fy as f32],
        [rig.width as f32, rig.height as f32],
    )
    .with_principal_point([c.cx as f32, c.cy as f32])
}

struct Logger {
    recording: RecordingStream,
    camera: CameraRig,
    /// Per map: each logged keyframe's last logged position.
    keyframes: BTreeMap<usize, BTreeMap<u64, [f64; 3]>>,
}

impl Logger {
    fn set_time(&self, index: usize, timestamp: f64) {
        self.recording.set_time_sequence("frame", index as i64);
        self.recording.set_duration_secs("time", timestamp);
    }

    fn frame(&self, f: &FrameMessage) -> Result<()> {
        self.set_time(f.index, f.timestamp);
        let rec = &self.recording;
        if let Some(pose) = &f.pose_wc {
            rec.log("world/camera", &transform(pose))?;
        }
        if let Some(jpeg) = jpeg(&f.image, self.camera.width, self.camera.height) {
            rec.log(
                "world/camera/image",
                &rerun::EncodedImage::from_file_contents(jpeg)
                    .with_media_type(rerun::MediaType::jpeg()),
            )?;
        }
        match &f.keypoints {
            Some(view) => {
                let colours = view
                    .tracked
                    .iter()
                    .map(|&t| if t { TRACKED } else { UNTRACKED });
                rec.log(
                    "world/camera/image/keypoints",
                    &rerun::Points2D::new(view.keypoints.iter().copied())
                        .with_colors(colours.map(colour))
                        .with_radii([2.0f32]),
                )?;
            }
            None => rec.log("world/camera/image/keypoints", &rerun::Clear::flat())?,
        }
        rec.log(
            "tracking/inliers",
            &rerun::Scalars::single(f.inliers as f64),
        )?;
        rec.log(
            "tracking/keyframe",
            &rerun::Scalars::single(if f.keyframe { 1.0 } else { 0.0 }),
        )?;
        for (name, ms) in ["extraction_ms", "tracking_ms", "mapping_ms"]
            .iter()
            .zip(f.timings_ms)
        {
            rec.log(format!("timings/{name}"), &rerun::Scalars::single(ms))?;
        }
        Ok(())
    }

    fn maps(&mut self, m: &MapsMessage) -> Result<()> {
        self.set_time(m.index, m.timestamp);
        let rec = &self.recording;
        rec.log(
            "world/trajectory/estimate",
            &rerun::LineStrips3D::new([m.trajectory.clone()])
                .with_colors([rerun::Color::from_rgb(230, 90, 40)]),
        )?;
        if !m.edges.is_empty() {
            let strips = m.edges.iter().map(|(a, b)| vec![*a, *b]);
            rec.log(
                "world/edges",
                &rerun::LineStrips3D::new(strips)
                    .with_colors([rerun::Color::from_rgb(230, 40, 200)])
                    .with_radii([0.05f32]),
            )?;
        }
        let frustum = pinhole(&self.camera).with_image_plane_distance(FRUSTUM_DEPTH_M);
        for map in &m.maps {
            let map_colour = MAP_COLOURS[map.map % MAP_COLOURS.len()];
            rec.log(
                format!("world/maps/{}/points", map.map),
                &rerun::Points3D::new(map.points.iter().copied())
                    .with_colors([colour(map_colour)])
                    .with_radii([0.03f32]),
            )?;
            let logged = self.keyframes.entry(map.map).or_default();
            let mut live = BTreeMap::new();
            for kf in &map.keyframes {
                let t = kf.pose_wc.to_isometry().translation.vector;
                let now = [t.x, t.y, t.z];
                live.insert(kf.id, now);
                let moved = logged.get(&kf.id).is_none_or(|before| {
                    let d: f64 = (0..3).map(|k| (before[k] - now[k]).powi(2)).sum();
                    d.sqrt() > KEYFRAME_MOVED_M
                });
                if moved {
                    let path = format!("world/maps/{}/keyframes/{}", map.map, kf.id);
                    rec.log(path.as_str(), &transform(&kf.pose_wc))?;
                    rec.log(path.as_str(), &frustum)?;
                }
            }
            for gone in logged.keys().filter(|id| !live.contains_key(id)) {
                rec.log(
                    format!("world/maps/{}/keyframes/{gone}", map.map),
                    &rerun::Clear::recursive(),
                )?;
            }
            *logged = live;
        }
        // A map merged into another is no longer listed: clear it.
        let listed: Vec<usize> = m.maps.iter().map(|v| v.map).collect();
        let stale: Vec<usize> = self
            .keyframes
            .keys()
            .copied()
            .filter(|k| !listed.contains(k))
            .collect();
        for map in stale {
            rec.log(format!("world/maps/{map}"), &rerun::Clear::recursive())?;
            self.keyframes.remove(&map);
        }
        Ok(())
    }
}

/// Logs until the feed closes the queue; flushes the recording at the end.
pub fn run(
    recording: RecordingStream,
    camera: CameraRig,
    messages: Receiver<ViewerMessage>,
) -> Result<()> {
    recording.log_static("world", &rerun::ViewCoordinates::RDF())?;
    recording.log_static("world/camera/image", &pinhole(&camera))?;
    let mut logger = Logger {
        recording,
        camera,
        keyframes: BTreeMap::new(),
    };
    while let Ok(message) = messages.recv() {
        match message {
            ViewerMessage::Frame(frame) => logger.frame(&frame)?,
            ViewerMessage::Maps(maps) => logger.maps(&maps)?,
            ViewerMessage::GroundTruth(positions) => logger.recording.log_static(
                "world/trajectory/ground_truth",
                &rerun::LineStrips3D::new([positions])
                    .with_colors([rerun::Color::from_rgb(60, 60, 60)]),
            )?,
        }
    }
    logger
        .recording
        .flush_blocking()
        .context("the recording could not be flushed")?;
    Ok(())
}
