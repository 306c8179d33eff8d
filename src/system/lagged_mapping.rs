//! A deterministic slow machine: inline local mapping that finishes each
//! keyframe only a fixed number of frames after it began.
//!
//! The mapping thread's `slowdown` hook reproduces a slow machine with
//! real sleeps, so what tracking sees depends on the scheduler and the
//! load. This queue reproduces it in frame time instead: keyframes wait
//! in order, the first one is "in service" for `frames_per_keyframe`
//! frames (one when another keyframe already waits, see
//! [`LaggedMapping::due`]), and only then does local mapping run on it
//! (between two frames, on the caller's thread). Tracking meanwhile sees
//! the queue's length, as it sees the thread's backlog, so the keyframe
//! decision, the points local mapping has not triangulated yet and the
//! BA not yet run are those of a mapper that needs `frames_per_keyframe`
//! frames per keyframe, and every run is the same.
//!
//! With a camera at 10 fps, `frames_per_keyframe = 5` is local mapping
//! five times slower than it is here (about 100 ms per keyframe for ORB
//! or SuperPoint + ANMS at 480×360 on a 2-core Xeon).

use std::collections::VecDeque;

use crate::map::{KeyFrameId, MapPointId};
use crate::mapping::BEFORE_BUNDLE_SHARE;

/// A keyframe waiting for local mapping.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) struct LaggedJob {
    /// The keyframe.
    pub keyframe: KeyFrameId,
    /// The points tracking created with it.
    pub created: Vec<MapPointId>,
    /// The index of the record of the frame that made it.
    pub record: usize,
}

/// How much of local mapping's work a lagged keyframe gets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum LaggedStep {
    /// Every step.
    Full,
    /// Tracking interrupted the local BA (ORB-SLAM3's `InterruptBA`) before
    /// it could finish: points, fusion and culling done, the BA cut off
    /// after `frames_done` of the `frames` its work takes (it keeps that
    /// share of its iterations, as an interrupted BA keeps what it reached).
    BundleInterrupted {
        /// Frames the BA ran before the interrupt ended it.
        frames_done: usize,
        /// Frames the whole BA takes.
        frames: usize,
    },
    /// Another keyframe was queued before fusion: fusion, BA and culling
    /// are left to it (ORB-SLAM3's `CheckNewKeyFrames`).
    LeftToNext,
}

/// The queue of a mapper that needs `frames_per_keyframe` frames per keyframe.
#[derive(Debug, Clone)]
pub(super) struct LaggedMapping {
    frames_per_keyframe: usize,
    queue: VecDeque<(usize, LaggedJob)>,
    /// The frame at which the first job's service began.
    head_started: usize,
    /// The frame at which tracking first interrupted the first job's BA.
    head_interrupted: Option<usize>,
}

impl LaggedStep {
    /// The share of the local BA's work this step leaves it: 1 unless
    /// the BA was interrupted.
    pub fn bundle_share(&self) -> f64 {
        match *self {
            LaggedStep::BundleInterrupted {
                frames_done,
                frames,
            } if frames > 0 => frames_done as f64 / frames as f64,
            LaggedStep::BundleInterrupted { .. } => 0.0,
            LaggedStep::Full | LaggedStep::LeftToNext => 1.0,
        }
    }
}

impl LaggedMapping {
    /// A mapper that finishes one keyframe every `frames_per_keyframe`
    /// frames (at least 1: the keyframe is mapped before the next frame).
    pub fn new(frames_per_keyframe: usize) -> Self {
        Self {
            frames_per_keyframe: frames_per_keyframe.max(1),
            queue: VecDeque::new(),
            head_started: 0,
            head_interrupted: None,
        }
    }

    /// Keyframes not finished yet (the one in service included): what
    /// tracking's keyframe decision sees as the mapping queue.
    pub fn pending(&self) -> usize {
        self.queue.len()
    }

    /// Frames a keyframe's work takes before its local BA.
    fn frames_before_bundle(&self) -> usize {
        ((self.frames_per_keyframe as f64 * BEFORE_BUNDLE_SHARE).ceil() as usize).max(1)
    }

    /// Queues a keyframe made at frame `frame`.
    pub fn submit(&mut self, frame: usize, job: LaggedJob) {
        if self.queue.is_empty() {
            self.head_started = frame;
            self.head_interrupted = None;
        }
        self.queue.push_back((frame, job));
    }

    /// Tracking at frame `frame` interrupted the BA of the keyframe in
    /// service (ORB-SLAM3's `InterruptBA`, see
    /// [`crate::tracking::TrackOutcome::interrupt_mapping`]): it ends one
    /// frame later, or when its work before the BA is done if that is
    /// later. An interrupt during the work before the BA counts too (the
    /// thread's flag raised then is lowered after triangulation; monocular
    /// tracking, which alone interrupts, asks again on the next frame).
    pub fn interrupt(&mut self, frame: usize) {
        if !self.queue.is_empty() && self.head_interrupted.is_none() {
            self.head_interrupted = Some(frame);
        }
    }

    /// The jobs finished by the time frame `frame` arrives, in order,
    /// each with how much of the work it got. The next job's service
    /// begins when the previous one ends (or when it was submitted, if
    /// later).
    ///
    /// A job costs `frames_per_keyframe` frames, unless:
    /// - another keyframe was queued by the end of its first frame: local
    ///   mapping then leaves fusion and BA to that one (ORB-SLAM3's
    ///   `CheckNewKeyFrames`), and the job costs one frame. Those two steps
    ///   are about 80 % of local mapping's time (SuperPoint + ANMS at
    ///   480×360: fusion 20 and BA 65 of 107 ms per keyframe), so a backlog
    ///   drains at about one keyframe per frame, as it does on the thread;
    /// - tracking interrupted its BA at frame `f` ([`Self::interrupt`]): it
    ///   ends at `f + 1`, but not before the work before the BA (40 % of
    ///   the lag, at least a frame) is done; its BA had the frames from
    ///   that work's end to its own.
    pub fn due(&mut self, frame: usize) -> Vec<(LaggedJob, LaggedStep)> {
        let mut done = Vec::new();
        while !self.queue.is_empty() {
            let start = self.head_started;
            let full = start + self.frames_per_keyframe;
            let next_submitted = self.queue.get(1).map(|(submitted, _)| *submitted);
            let (finished_at, step) = if next_submitted.is_some_and(|s| s <= start + 1) {
                (start + 1, LaggedStep::LeftToNext)
            } else {
                let bundle_start = start + self.frames_before_bundle();
                let interrupted_end = self.head_interrupted.map(|at| (at + 1).max(bundle_start));
                match interrupted_end {
                    Some(end) if end < full => (
                        end,
                        LaggedStep::BundleInterrupted {
                            frames_done: end - bundle_start,
                            frames: full - bundle_start,
                        },
                    ),
                    _ => (full, LaggedStep::Full),
                }
            };
            if finished_at > frame {
                break;
            }
            let Some((_, job)) = self.queue.pop_front() else {
                break;
            };
            self.head_interrupted = None;
            if let Some(submitted) = next_submitted {
                self.head_started = finished_at.max(submitted);
            }
            done.push((job, step));
        }
        done
    }

    /// Every job still queued, in order (the run ends, a map is given up,
    /// a loop is corrected): all but the last leave their fusion and BA
    /// to the next.
    pub fn drain(&mut self) -> Vec<(LaggedJob, LaggedStep)> {
        let n = self.queue.len();
        self.head_interrupted = None;
        self.queue
            .drain(..)
            .enumerate()
            .map(|(i, (_, job))| {
                let step = if i + 1 < n {
                    LaggedStep::LeftToNext
                } else {
                    LaggedStep::Full
                };
                (job, step)
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::{LaggedJob, LaggedMapping, LaggedStep};
    use crate::map::KeyFrameId;

    fn job(record: usize) -> LaggedJob {
        LaggedJob {
            keyframe: KeyFrameId(record as u64),
            created: Vec::new(),
            record,
        }
    }

    /// (record, fusion and BA left to the next keyframe).
    fn records(done: &[(LaggedJob, LaggedStep)]) -> Vec<(usize, bool)> {
        done.iter()
            .map(|(j, step)| (j.record, *step == LaggedStep::LeftToNext))
            .collect()
    }

    #[test]
    fn a_keyframe_alone_costs_the_full_lag_and_one_with_a_successor_costs_a_frame() {
        let mut lag = LaggedMapping::new(3);
        lag.submit(10, job(10));
        lag.submit(12, job(12));
        assert_eq!(lag.pending(), 2);
        // 12 came after the first frame of service: the full 3 frames.
        assert!(lag.due(12).is_empty(), "in service from 10 until 13");
        assert_eq!(records(&lag.due(13)), vec![(10, false)]);
        assert_eq!(lag.pending(), 1);
        // The second began at 13, when the first ended.
        assert!(lag.due(15).is_empty());
        lag.submit(15, job(15));
        // 15 waits from 15 on, after 12's first frame (13 + 1): full lag.
        assert_eq!(records(&lag.due(16)), vec![(12, false)]);
        assert!(lag.due(18).is_empty());
        assert_eq!(records(&lag.due(19)), vec![(15, false)]);
        assert_eq!(lag.pending(), 0);
    }

    #[test]
    fn a_backlog_drains_one_keyframe_per_frame_with_fusion_and_ba_skipped() {
        let mut lag = LaggedMapping::new(5);
        for f in 0..4 {
            lag.submit(f, job(f));
        }
        assert_eq!(records(&lag.due(2)), vec![(0, true), (1, true)]);
        // The last one has no successor: it is mapped in full, 5 frames.
        assert_eq!(records(&lag.due(3)), vec![(2, true)]);
        assert!(lag.due(7).is_empty());
        assert_eq!(records(&lag.due(8)), vec![(3, false)]);
    }

    #[test]
    fn an_interrupted_ba_ends_the_keyframe_a_frame_later_but_not_before_its_points() {
        let steps = |done: &[(LaggedJob, LaggedStep)]| -> Vec<(usize, LaggedStep)> {
            done.iter().map(|(j, step)| (j.record, *step)).collect()
        };
        // Lag 5: the work before the BA takes ceil(0.4 × 5) = 2 frames.
        let mut lag = LaggedMapping::new(5);
        lag.submit(0, job(0));
        lag.interrupt(1);
        assert!(lag.due(1).is_empty(), "the points are not made yet");
        let none_of_three = LaggedStep::BundleInterrupted {
            frames_done: 0,
            frames: 3,
        };
        assert_eq!(steps(&lag.due(2)), vec![(0, none_of_three)]);
        assert_eq!(none_of_three.bundle_share(), 0.0);
        // Interrupted in its fourth frame: it ends at the next one.
        lag.submit(2, job(2));
        lag.interrupt(5);
        lag.interrupt(3); // only the first interrupt counts
        assert!(lag.due(5).is_empty());
        let two_of_three = LaggedStep::BundleInterrupted {
            frames_done: 2,
            frames: 3,
        };
        assert_eq!(steps(&lag.due(6)), vec![(2, two_of_three)]);
        assert!((two_of_three.bundle_share() - 2.0 / 3.0).abs() < 1e-12);
        assert_eq!(LaggedStep::Full.bundle_share(), 1.0);
        // An interrupt in the last frame changes nothing.
        lag.submit(10, job(10));
        lag.interrupt(14);
        assert_eq!(steps(&lag.due(15)), vec![(10, LaggedStep::Full)]);
        // An interrupt with a keyframe queued behind: the next one's
        // service begins when the interrupted one ends.
        lag.submit(20, job(20));
        lag.interrupt(23);
        lag.submit(23, job(23));
        assert_eq!(steps(&lag.due(24)), vec![(20, two_of_three)]);
        assert!(lag.due(28).is_empty(), "23's service began at 24");
        assert_eq!(steps(&lag.due(29)), vec![(23, LaggedStep::Full)]);
        // Nothing in service: an interrupt is ignored.
        lag.interrupt(30);
        lag.submit(31, job(31));
        assert_eq!(steps(&lag.due(36)), vec![(31, LaggedStep::Full)]);
    }

    #[test]
    fn an_idle_mapper_starts_a_keyframe_when_it_arrives() {
        let mut lag = LaggedMapping::new(2);
        lag.submit(0, job(0));
        assert_eq!(records(&lag.due(2)), vec![(0, false)]);
        lag.submit(9, job(9));
        assert!(lag.due(10).is_empty(), "service began at 9, not at 2");
        assert_eq!(records(&lag.due(11)), vec![(9, false)]);
    }

    #[test]
    fn a_late_frame_collects_every_finished_keyframe_and_drain_takes_the_rest() {
        let mut lag = LaggedMapping::new(4);
        for f in 0..4 {
            lag.submit(f, job(f));
        }
        assert_eq!(records(&lag.due(2)), vec![(0, true), (1, true)]);
        assert_eq!(records(&lag.drain()), vec![(2, true), (3, false)]);
        assert_eq!(lag.pending(), 0);
    }
}
