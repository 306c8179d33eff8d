//! The extraction stage of `spslam run` on its own thread: it reads frame
//! t+1 and extracts both images' features while the caller tracks frame t,
//! through a bounded queue ([`QUEUE_DEPTH`] prepared frames at most).
//!
//! Thread budget (the rule `spslam run` follows): the extraction stage owns
//! the cores. Its left and right ONNX Runtime sessions run in parallel with
//! `max(1, cores / 2)` intra-op threads each, so that together they fill the
//! machine; tracking (tens of ms per frame) and local mapping (its own
//! thread, mostly idle between keyframes) take what extraction leaves while
//! it waits on the queue. Giving the two sessions more than the cores, or a
//! session per stage on top, only adds context switches: on the 2-core
//! machine of `BENCHMARKS.md` the sessions get one thread each.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender};
use std::time::Instant;

use spslam::error::{panic_message, SlamError};
use spslam::tracking::{Extractors, SensorFeatures};

use super::source::{InputFrame, LoadedImages, Source, Unreadable};

/// How many prepared frames may wait for tracking. One is enough to hide
/// extraction behind tracking; more only holds images in memory.
pub const QUEUE_DEPTH: usize = 1;

/// A frame read and extracted, ready for stereo matching and tracking.
pub struct PreparedFrame {
    /// The frame's images.
    pub images: LoadedImages,
    /// Its features (both images' for stereo).
    pub features: SensorFeatures,
    /// Wall time of the extraction (both images, in parallel), in ms.
    pub extraction_ms: f64,
}

/// How frames are read: the first frame's size, the depth images' units.
#[derive(Debug, Clone, Copy)]
pub struct Reading {
    /// Every image must have this size (the first frame's).
    pub size: (usize, usize),
    /// Depth units per metre (`DepthMapFactor`).
    pub depth_factor: f64,
}

/// Why a frame could not be prepared.
#[derive(Debug, thiserror::Error)]
pub enum PrepareError {
    /// An image could not be read.
    #[error("{0}")]
    Unreadable(Unreadable),
    /// The extractor rejected the pair.
    #[error("{0}")]
    Extraction(SlamError),
    /// The extraction stage panicked (a bug).
    #[error("the extraction stage panicked: {message}")]
    Panicked {
        /// The panic's message.
        message: String,
    },
}

/// One item of the queue: frame `index` and how its preparation went.
pub struct Prepared {
    /// The frame's index in the requested frames.
    pub index: usize,
    /// Its images and features, or why there are none.
    pub result: Result<PreparedFrame, PrepareError>,
}

/// Runs the extraction stage over `frames` on a scoped thread and hands
/// the receiving end of its queue to `consume`. When `consume` returns
/// (early, on a signal or a fatal error, or after the last frame) the
/// queue is dropped and the stage stops after the frame in hand.
pub fn with_extraction_stage<R>(
    source: &Source,
    frames: &[InputFrame],
    reading: Reading,
    extractors: Extractors,
    consume: impl FnOnce(&Receiver<Prepared>) -> R,
) -> R {
    let (sender, receiver) = sync_channel(QUEUE_DEPTH);
    std::thread::scope(|scope| {
        scope.spawn(move || prepare_all(source, frames, reading, extractors, sender));
        let result = consume(&receiver);
        drop(receiver);
        result
    })
}

fn prepare_all(
    source: &Source,
    frames: &[InputFrame],
    reading: Reading,
    mut extractors: Extractors,
    sender: SyncSender<Prepared>,
) {
    for (index, frame) in frames.iter().enumerate() {
        let result = catch_unwind(AssertUnwindSafe(|| {
            prepare(source, frame, reading, index, &mut extractors)
        }))
        .unwrap_or_else(|payload| {
            Err(PrepareError::Panicked {
                message: panic_message(payload.as_ref()),
            })
        });
        let panicked = matches!(result, Err(PrepareError::Panicked { .. }));
        if sender.send(Prepared { index, result }).is_err() || panicked {
            return; // the consumer stopped, or the extractors are unusable
        }
    }
}

fn prepare(
    source: &Source,
    frame: &InputFrame,
    reading: Reading,
    index: usize,
    extractors: &mut Extractors,
) -> Result<PreparedFrame, PrepareError> {
    let images = source
        .load(frame, Some(reading.size), reading.depth_factor)
        .map_err(PrepareError::Unreadable)?;
    let start = Instant::now();
    let features = extractors
        .extract(index, images.views())
        .map_err(PrepareError::Extraction)?;
    Ok(PreparedFrame {
        images,
        features,
        extraction_ms: start.elapsed().as_secs_f64() * 1e3,
    })
}
