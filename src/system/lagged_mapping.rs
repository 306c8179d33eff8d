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

/// The queue of a mapper that needs `frames_per_keyframe` frames per keyframe.
#[derive(Debug, Clone)]
pub(super) struct LaggedMapping {
    frames_per_keyframe: usize,
    queue: VecDeque<(usize, LaggedJob)>,
    /// The frame at which the first job's service began.
    head_started: usize,
}

impl LaggedMapping {
    /// A mapper that finishes one keyframe every `frames_per_keyframe`
    /// frames (at least 1: the keyframe is mapped before the next frame).
    pub fn new(frames_per_keyframe: usize) -> Self {
        Self {
            frames_per_keyframe: frames_per_keyframe.max(1),
            queue: VecDeque::new(),
            head_started: 0,
        }
    }

    /// Keyframes not finished yet (the one in service included): what
    /// tracking's keyframe decision sees as the mapping queue.
    pub fn pending(&self) -> usize {
        self.queue.len()
    }

    /// Queues a keyframe made at frame `frame`.
    pub fn submit(&mut self, frame: usize, job: LaggedJob) {
        if self.queue.is_empty() {
            self.head_started = frame;
        }
        self.queue.push_back((frame, job));
    }

    /// The jobs finished by the time frame `frame` arrives, in order,
    /// each with whether its fusion and BA are skipped. The next job's
    /// service begins when the previous one ends (or when it was
    /// submitted, if later).
    ///
    /// A job costs `frames_per_keyframe` frames, unless another keyframe
    /// was queued by the end of its first frame: local mapping then leaves
    /// fusion and BA to that one (ORB-SLAM3's `CheckNewKeyFrames`), and
    /// the job costs one frame. Those two steps are about 80 % of local
    /// mapping's time (SuperPoint + ANMS at 480×360: fusion 20 and BA 65
    /// of 107 ms per keyframe), so a backlog drains at about one keyframe
    /// per frame, as it does on the mapping thread.
    pub fn due(&mut self, frame: usize) -> Vec<(LaggedJob, bool)> {
        let mut done = Vec::new();
        while !self.queue.is_empty() {
            let start = self.head_started;
            let next_submitted = self.queue.get(1).map(|(submitted, _)| *submitted);
            let skipped = next_submitted.is_some_and(|submitted| submitted <= start + 1);
            let cost = if skipped { 1 } else { self.frames_per_keyframe };
            let finished_at = start + cost;
            if finished_at > frame {
                break;
            }
            let Some((_, job)) = self.queue.pop_front() else {
                break;
            };
            if let Some(submitted) = next_submitted {
                self.head_started = finished_at.max(submitted);
            }
            done.push((job, skipped));
        }
        done
    }

    /// Every job still queued, in order (the run ends, a map is given up,
    /// a loop is corrected); the bool as in [`Self::due`].
    pub fn drain(&mut self) -> Vec<(LaggedJob, bool)> {
        let n = self.queue.len();
        self.queue
            .drain(..)
            .enumerate()
            .map(|(i, (_, job))| (job, i + 1 < n))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::{LaggedJob, LaggedMapping};
    use crate::map::KeyFrameId;

    fn job(record: usize) -> LaggedJob {
        LaggedJob {
            keyframe: KeyFrameId(record as u64),
            created: Vec::new(),
            record,
        }
    }

    fn records(done: &[(LaggedJob, bool)]) -> Vec<(usize, bool)> {
        done.iter().map(|(j, w)| (j.record, *w)).collect()
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
