//! The frame loop of `spslam run`: takes each pair from the extraction
//! stage ([`pipeline`](super::pipeline)), tracks it, skips (or, with
//! `--strict`, stops at) a frame that cannot be read, and stops
//! between frames when a signal asks it to. It never returns early with an
//! error: every way it ends is a [`RunEnd`], so that the caller writes the
//! outputs of the frames processed so far on every path.

use std::cell::RefCell;
use std::panic::{catch_unwind, AssertUnwindSafe};

use indicatif::ProgressBar;
use spslam::error::{panic_message, SlamError};
use spslam::system::SlamSystem;

use std::sync::mpsc::Receiver;

use super::memory_log::MemoryLog;
use super::pipeline::{PrepareError, Prepared, PreparedFrame};
use super::signals::StopRequest;
use super::source::{InputFrame, Unreadable, UnreadableCause};
use super::viewer::ViewerFeed;

/// Frames between two hand-backs of freed heap to the system
/// (`spslam::ffi::release_free_heap`): ten seconds of a 10 Hz camera.
const HEAP_RELEASE_FRAMES: usize = 100;

/// How a run ended.
#[derive(Debug, Clone, PartialEq)]
pub enum RunEnd {
    /// Every requested frame was processed (unreadable ones skipped).
    Complete,
    /// A signal stopped it between two frames.
    Interrupted {
        /// The signal's name (`SIGINT`, `SIGTERM`).
        signal: &'static str,
    },
    /// A fatal error (or `--strict` at an unreadable frame) stopped it.
    Failed {
        /// What went wrong.
        error: String,
    },
}

impl RunEnd {
    /// Whether every requested frame was processed.
    pub fn is_complete(&self) -> bool {
        matches!(self, Self::Complete)
    }

    /// `complete`, `interrupted` or `failed: <error>`, as report.json's `end`.
    pub fn label(&self) -> String {
        match self {
            Self::Complete => "complete".into(),
            Self::Interrupted { .. } => "interrupted".into(),
            Self::Failed { error } => format!("failed: {error}"),
        }
    }

    /// The signal that interrupted the run, if one did.
    pub fn signal(&self) -> Option<&'static str> {
        match self {
            Self::Interrupted { signal } => Some(signal),
            _ => None,
        }
    }
}

/// An input frame that was skipped because it could not be read.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct UnreadableFrame {
    /// Its index in the input sequence.
    pub index: usize,
    /// The image at fault.
    pub path: String,
    /// Why it could not be used.
    pub reason: String,
}

/// What the frame loop needs besides the system and the extraction stage.
pub struct FrameLoop<'a> {
    /// The frames requested.
    pub frames: &'a [InputFrame],
    /// Stop at the first unreadable frame instead of skipping it.
    pub strict: bool,
    /// Polled between frames.
    pub stop: &'a StopRequest,
    /// The progress bar; messages are printed above it.
    pub bar: &'a ProgressBar,
    /// `--memory-log`, sampled after every frame it asks for.
    pub memory_log: Option<&'a RefCell<MemoryLog>>,
    /// `--rerun`/`--viewer`: fed after every frame.
    pub viewer: Option<&'a RefCell<ViewerFeed>>,
}

/// One frame's outcome that is not a tracked record.
enum FrameError {
    /// The frame cannot be used: skip it (or stop, with `--strict`).
    Unreadable(Unreadable),
    /// The system failed: stop the run.
    Fatal(String),
}

impl FrameLoop<'_> {
    /// Tracks the frames in order, as the extraction stage hands them over,
    /// until the end, a signal or a fatal error; unreadable frames are
    /// recorded in `slam` as lost and listed in `unreadable`.
    pub fn run(
        &self,
        slam: &mut SlamSystem,
        prepared: &Receiver<Prepared>,
        unreadable: &mut Vec<UnreadableFrame>,
    ) -> RunEnd {
        let mut global_bas_seen = slam.global_ba_runs().len();
        for (index, frame) in self.frames.iter().enumerate() {
            if let Some(signal) = self.stop.requested() {
                return RunEnd::Interrupted { signal };
            }
            let next = match prepared.recv() {
                Ok(next) if next.index == index => next,
                Ok(next) => {
                    return RunEnd::Failed {
                        error: format!(
                            "the extraction stage handed over frame {} where {index} was due",
                            next.index
                        ),
                    }
                }
                Err(_) => {
                    return RunEnd::Failed {
                        error: format!("the extraction stage stopped before frame {index}"),
                    }
                }
            };
            // A signal that came while waiting for the frame stops before it.
            if let Some(signal) = self.stop.requested() {
                return RunEnd::Interrupted { signal };
            }
            match self.step(slam, index, frame, next.result) {
                Ok(()) => {}
                Err(FrameError::Unreadable(e)) if self.strict => {
                    return RunEnd::Failed {
                        error: format!("frame {index} cannot be read (--strict): {e}"),
                    };
                }
                Err(FrameError::Unreadable(e)) => {
                    self.bar.suspend(|| {
                        eprintln!("warning: frame {index} skipped (counted as lost): {e}");
                    });
                    slam.skip_unreadable(index, frame.timestamp, e.to_string());
                    unreadable.push(UnreadableFrame {
                        index,
                        path: e.path.display().to_string(),
                        reason: e.cause.to_string(),
                    });
                }
                Err(FrameError::Fatal(error)) => {
                    return RunEnd::Failed {
                        error: format!("frame {index}: {error}"),
                    };
                }
            }
            self.bar.inc(1);
            // The log's sample comes before the hand-back below, so that it
            // sees what the allocator kept since the last one.
            if let Some(log) = self.memory_log {
                if let Err(e) = log.borrow_mut().after_frame(index + 1, slam) {
                    // Asked for and not written (a full disk): stop, and
                    // write the outputs of the frames so far.
                    return RunEnd::Failed {
                        error: format!("the memory log failed: {e:#}"),
                    };
                }
            }
            // Freed heap goes back to the system after each global BA (its
            // working set, the whole map's problem, is freed when it is
            // applied) and every HEAP_RELEASE_FRAMES frames: glibc keeps
            // freed memory in its arenas, and without this a soak run's
            // kept heap rose from 74 to 312 MiB (EVALUATION.md, 'Soak').
            let global_ba_applied = slam.global_ba_runs().len() > global_bas_seen;
            if global_ba_applied || (index + 1).is_multiple_of(HEAP_RELEASE_FRAMES) {
                global_bas_seen = slam.global_ba_runs().len();
                let start = std::time::Instant::now();
                spslam::ffi::release_free_heap();
                if let Some(log) = self.memory_log {
                    log.borrow_mut()
                        .heap_released(start.elapsed().as_secs_f64() * 1e3);
                }
            }
        }
        RunEnd::Complete
    }

    /// Tracks one prepared frame.
    fn step(
        &self,
        slam: &mut SlamSystem,
        index: usize,
        frame: &InputFrame,
        prepared: Result<PreparedFrame, PrepareError>,
    ) -> Result<(), FrameError> {
        let prepared = prepared.map_err(|e| match e {
            PrepareError::Unreadable(e) => FrameError::Unreadable(e),
            PrepareError::Extraction(e) => classify(e, frame),
            e @ PrepareError::Panicked { .. } => FrameError::Fatal(e.to_string()),
        })?;
        // A panic in the system (a bug) ends the run like a fatal error,
        // so that the frames before it are still written.
        let outcome = catch_unwind(AssertUnwindSafe(|| {
            slam.process_features(
                index,
                frame.timestamp,
                prepared.features,
                prepared.images.views(),
                prepared.extraction_ms,
            )
            .map(|record| (record.state, record.inliers))
        }));
        if let (Some(viewer), Ok(Ok(_))) = (self.viewer, &outcome) {
            viewer
                .borrow_mut()
                .after_frame(slam, Some(prepared.images.views().left()));
        }
        match outcome {
            Ok(Ok((state, inliers))) => {
                tracing::debug!(frame = index, ?state, inliers, "frame processed");
                self.bar
                    .set_message(format!("{state:?}, {inliers} inliers"));
                Ok(())
            }
            Ok(Err(e)) => Err(classify(e, frame)),
            Err(payload) => Err(FrameError::Fatal(format!(
                "the system panicked: {}",
                panic_message(payload.as_ref())
            ))),
        }
    }
}

/// Per-frame input errors make the frame unreadable; the others are fatal.
fn classify(error: SlamError, frame: &InputFrame) -> FrameError {
    match error {
        SlamError::ImageSizeMismatch {
            left_width,
            left_height,
            right_width,
            right_height,
            ..
        } => FrameError::Unreadable(Unreadable {
            path: frame.right.clone().unwrap_or_else(|| frame.image.clone()),
            cause: UnreadableCause::StereoSizeMismatch {
                left_width,
                left_height,
                right_width,
                right_height,
            },
        }),
        SlamError::Features { source, .. } => FrameError::Unreadable(Unreadable {
            path: frame.image.clone(),
            cause: UnreadableCause::Features(source.to_string()),
        }),
        other => FrameError::Fatal(other.to_string()),
    }
}
