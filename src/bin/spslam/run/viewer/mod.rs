//! `spslam run --rerun FILE.rrd | --rerun-connect [URL] | --viewer`: the
//! run as it happens, in rerun's 3-D viewer.
//!
//! The frame loop hands this feed copies taken from the system between
//! frames (the pose, the frame's keypoints, every tenth frame the maps);
//! a thread of its own turns them into rerun's archetypes and logs them.
//! The queue between the two is bounded: when the logging thread falls
//! behind, frames are dropped from the viewer, never from SLAM, and the
//! count is reported at the end. A viewer that goes away (closed, or it
//! could not start) never holds the run: a streaming feed gets
//! [`STREAM_FINISH_TIMEOUT`] to hand over its last messages, and the run's
//! outputs are written before the feed finishes. The rerun SDK is compiled
//! in with the `viewer` cargo feature only (`make demo` and `make test`
//! build it).

// Without the `viewer` feature the feed refuses to start, and nothing
// reads its messages.
#![cfg_attr(not(feature = "viewer"), allow(dead_code))]

#[cfg(feature = "viewer")]
mod rerun_log;

use std::path::PathBuf;
use std::sync::mpsc::{sync_channel, SyncSender, TrySendError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use anyhow::{bail, Result};
use spslam::camera::CameraRig;
use spslam::eval::Trajectory;
use spslam::features::GrayImageView;
use spslam::optim::Se3;
use spslam::system::{FrameView, MapView, SlamSystem};

/// Frames the logging thread may fall behind before frames are dropped.
const QUEUE_FRAMES: usize = 32;
/// The maps are copied every this many frames (and at the end).
const MAP_EVERY_FRAMES: usize = 10;
/// How long the end of a run waits for a streamed recording (`--viewer`,
/// `--rerun-connect`) to take its last messages. A viewer that is still
/// there takes a few frames' worth in well under a second; one that was
/// closed, or never started, takes nothing, and the rerun SDK would wait
/// for it forever. A file (`--rerun FILE`) is always waited for.
pub const STREAM_FINISH_TIMEOUT: Duration = Duration::from_secs(20);
/// How often the end of a run checks whether the logging thread is done.
const FINISH_POLL: Duration = Duration::from_millis(20);

/// Where the recording goes.
#[derive(Debug, Clone, PartialEq)]
pub enum ViewerTarget {
    /// A `.rrd` file (`--rerun FILE`).
    File(PathBuf),
    /// A running viewer (`--rerun-connect [URL]`).
    Connect(String),
    /// A viewer started for this run (`--viewer`), from `executable`.
    Spawn {
        /// The `rerun` executable.
        executable: PathBuf,
    },
}

/// One message to the logging thread.
pub enum ViewerMessage {
    /// One processed frame.
    Frame(Box<FrameMessage>),
    /// The maps, the corrected trajectory and the loop and merge edges.
    Maps(Box<MapsMessage>),
    /// The ground truth, aligned to the estimate (at the end of a run).
    GroundTruth(Vec<[f32; 3]>),
}

/// What is shown for one frame.
pub struct FrameMessage {
    /// Its index (the `frame` timeline).
    pub index: usize,
    /// Its timestamp, seconds (the `time` timeline).
    pub timestamp: f64,
    /// `T_wc` when it was tracked.
    pub pose_wc: Option<Se3>,
    /// The left (or only) image, row-major gray bytes.
    pub image: Vec<u8>,
    /// Its keypoints and which track map points (when it was tracked).
    pub keypoints: Option<FrameView>,
    /// Inliers of the pose.
    pub inliers: usize,
    /// Whether it became a keyframe.
    pub keyframe: bool,
    /// Stage times, milliseconds: extraction, tracking, mapping.
    pub timings_ms: [f64; 3],
}

/// A copy of the maps.
pub struct MapsMessage {
    /// The frame after which it was taken.
    pub index: usize,
    /// Its timestamp.
    pub timestamp: f64,
    /// Every anchored map.
    pub maps: Vec<MapView>,
    /// The whole estimated trajectory's positions (as corrected so far).
    pub trajectory: Vec<[f32; 3]>,
    /// Accepted loops and merges as pairs of positions on the trajectory.
    pub edges: Vec<([f32; 3], [f32; 3])>,
}

/// The frame loop's side of the viewer.
pub struct ViewerFeed {
    sender: Option<SyncSender<ViewerMessage>>,
    thread: Option<JoinHandle<Result<()>>>,
    counts: ViewerCounts,
    /// How long [`Self::finish`] waits; `None`: as long as it takes.
    finish_timeout: Option<Duration>,
}

/// What reached the logging thread.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ViewerCounts {
    /// Frames handed over.
    pub frames: usize,
    /// Copies of the maps handed over.
    pub maps: usize,
    /// Frames (or map copies) dropped because the queue was full.
    pub dropped: usize,
}

fn position(pose: &Se3) -> [f32; 3] {
    let t = pose.to_isometry().translation.vector;
    [t.x as f32, t.y as f32, t.z as f32]
}

impl ViewerFeed {
    /// Starts the logging thread and opens the recording.
    /// `camera`: the rig's intrinsics and image size draw the frusta and the frame.
    pub fn start(target: ViewerTarget, camera: CameraRig, title: String) -> Result<Self> {
        #[cfg(feature = "viewer")]
        {
            let (sender, receiver) = sync_channel(QUEUE_FRAMES);
            let finish_timeout = match target {
                ViewerTarget::File(_) => None,
                ViewerTarget::Connect(_) | ViewerTarget::Spawn { .. } => {
                    Some(STREAM_FINISH_TIMEOUT)
                }
            };
            let recording = rerun_log::open(&target, &title)?;
            let thread = std::thread::Builder::new()
                .name("viewer".into())
                .spawn(move || rerun_log::run(recording, camera, receiver))?;
            Ok(Self {
                sender: Some(sender),
                thread: Some(thread),
                counts: ViewerCounts::default(),
                finish_timeout,
            })
        }
        #[cfg(not(feature = "viewer"))]
        {
            let _ = (target, camera, title, sync_channel::<ViewerMessage>);
            bail!("this spslam was built without the viewer: build it with `cargo build --release --features viewer` (`make demo` does)")
        }
    }

    fn send(&mut self, message: ViewerMessage) {
        let Some(sender) = &self.sender else {
            return;
        };
        let is_frame = matches!(message, ViewerMessage::Frame(_));
        match sender.try_send(message) {
            Ok(()) if is_frame => self.counts.frames += 1,
            Ok(()) => self.counts.maps += 1,
            Err(TrySendError::Full(_)) => self.counts.dropped += 1,
            // The logging thread stopped (its error is reported at the end).
            Err(TrySendError::Disconnected(_)) => self.sender = None,
        }
    }

    /// After each processed frame: the pose, the image and keypoints, and
    /// every tenth frame the maps.
    pub fn after_frame(&mut self, slam: &SlamSystem, image: Option<GrayImageView<'_>>) {
        let Some(record) = slam.records().last() else {
            return;
        };
        let index = record.index;
        let pose_wc = slam.last_pose().ok().flatten();
        let keypoints = slam.frame_view().filter(|view| view.index == index);
        let image = image
            .map(|view| {
                (0..view.height())
                    .flat_map(|y| view.row(y).iter().copied())
                    .collect()
            })
            .unwrap_or_default();
        self.send(ViewerMessage::Frame(Box::new(FrameMessage {
            index,
            timestamp: record.timestamp,
            pose_wc,
            image,
            keypoints,
            inliers: record.inliers,
            keyframe: record.keyframe,
            timings_ms: [
                record.timings.extraction_ms,
                record.timings.tracking_ms,
                record.timings.mapping_ms,
            ],
        })));
        if (index + 1) % MAP_EVERY_FRAMES == 0 {
            if let Some(maps) = maps_message(slam) {
                self.send(ViewerMessage::Maps(Box::new(maps)));
            }
        }
    }

    /// At the end of the run: the final maps and the aligned ground truth,
    /// then the logging thread's end. A file is waited for as long as it
    /// takes; a stream for [`STREAM_FINISH_TIMEOUT`], after which the
    /// logging thread is left behind (the process ends without it) and the
    /// error says that the viewer stopped taking data.
    pub fn finish(
        mut self,
        slam: &SlamSystem,
        ground_truth: Option<Vec<[f32; 3]>>,
    ) -> Result<ViewerCounts> {
        let deadline = self.finish_timeout.map(|timeout| Instant::now() + timeout);
        let timed_out = || {
            anyhow::anyhow!(
                "the viewer took no data for {} s (was it closed, or could it not start? \
                 its own messages are above); the end of the recording was not shown",
                STREAM_FINISH_TIMEOUT.as_secs()
            )
        };
        if let Some(sender) = self.sender.take() {
            if let Some(maps) = maps_message(slam) {
                match send_until(&sender, ViewerMessage::Maps(Box::new(maps)), deadline) {
                    SendOutcome::Sent => self.counts.maps += 1,
                    SendOutcome::Closed => {}
                    SendOutcome::TimedOut => return Err(timed_out()),
                }
            }
            if let Some(gt) = ground_truth {
                if send_until(&sender, ViewerMessage::GroundTruth(gt), deadline)
                    == SendOutcome::TimedOut
                {
                    return Err(timed_out());
                }
            }
        }
        if let Some(thread) = self.thread.take() {
            if let Some(deadline) = deadline {
                while !thread.is_finished() {
                    if Instant::now() >= deadline {
                        // Dropping the handle detaches the thread.
                        return Err(timed_out());
                    }
                    std::thread::sleep(FINISH_POLL);
                }
            }
            match thread.join() {
                Ok(result) => result?,
                Err(_) => bail!("the viewer's logging thread panicked"),
            }
        }
        Ok(self.counts)
    }
}

/// What became of a message [`send_until`] tried to hand over.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum SendOutcome {
    Sent,
    /// The logging thread has stopped (its error comes with its end).
    Closed,
    TimedOut,
}

/// Sends, waiting for room in the queue until `deadline` (forever without one).
fn send_until(
    sender: &SyncSender<ViewerMessage>,
    message: ViewerMessage,
    deadline: Option<Instant>,
) -> SendOutcome {
    let Some(deadline) = deadline else {
        return match sender.send(message) {
            Ok(()) => SendOutcome::Sent,
            Err(_) => SendOutcome::Closed,
        };
    };
    let mut message = message;
    loop {
        match sender.try_send(message) {
            Ok(()) => return SendOutcome::Sent,
            Err(TrySendError::Disconnected(_)) => return SendOutcome::Closed,
            Err(TrySendError::Full(back)) => {
                if Instant::now() >= deadline {
                    return SendOutcome::TimedOut;
                }
                message = back;
                std::thread::sleep(FINISH_POLL);
            }
        }
    }
}

/// The maps, trajectory and edges now; `None` when they cannot be read.
fn maps_message(slam: &SlamSystem) -> Option<MapsMessage> {
    let record = slam.records().last()?;
    let maps = slam.map_views().ok()?;
    let poses = slam.trajectory().ok()?;
    let at = |frame: usize| {
        slam.records()
            .iter()
            .position(|r| r.index == frame)
            .and_then(|i| poses.get(i))
            .map(|(_, pose)| position(pose))
    };
    let loops = slam.loops().iter().map(|l| (l.query_frame, l.match_frame));
    let merges = slam.merges().iter().map(|m| (m.query_frame, m.match_frame));
    let edges = loops
        .chain(merges)
        .filter_map(|(q, m)| Some((at(q)?, at(m)?)))
        .collect();
    Some(MapsMessage {
        index: record.index,
        timestamp: record.timestamp,
        maps,
        trajectory: poses.iter().map(|(_, pose)| position(pose)).collect(),
        edges,
    })
}

/// The ground truth's positions in the estimate's frame: paired with the
/// estimate by row (KITTI layout) or by time (within 10 ms), aligned by
/// SE(3), or Sim(3) for a monocular run; `None` when too few pairs.
pub fn aligned_ground_truth(
    gt: &Trajectory,
    estimate: &[(f64, Se3)],
    by_row: bool,
    metric: bool,
) -> Option<Vec<[f32; 3]>> {
    use spslam::eval::report::{pair_trajectories, Pairing};
    use spslam::eval::{ate::alignment_transform, Alignment};
    let estimate = Trajectory::new(
        estimate.iter().map(|(t, _)| *t).collect(),
        estimate.iter().map(|(_, p)| p.to_isometry()).collect(),
    );
    let pair = if by_row {
        let n = gt.len().min(estimate.len());
        let rows: Vec<usize> = (0..n).collect();
        spslam::eval::AssociatedPair {
            reference: estimate.select(&rows),
            estimate: gt.select(&rows),
        }
    } else {
        let paired = pair_trajectories(
            gt,
            &estimate,
            Pairing::ByTimestamp {
                max_diff: spslam::eval::DEFAULT_MAX_DIFF,
                one_to_one: true,
            },
        )
        .ok()?;
        spslam::eval::AssociatedPair {
            reference: paired.estimate,
            estimate: paired.reference,
        }
    };
    if pair.reference.len() < 3 {
        return None;
    }
    let alignment = if metric {
        Alignment::Se3
    } else {
        Alignment::Sim3
    };
    let sim = alignment_transform(&pair.reference, &pair.estimate, alignment).ok()?;
    let aligned = gt.transformed(&sim.transform, sim.scale);
    Some(
        aligned
            .positions()
            .iter()
            .map(|p| [p.x as f32, p.y as f32, p.z as f32])
            .collect(),
    )
}
