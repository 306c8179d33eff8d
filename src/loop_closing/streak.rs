//! The confirmation streak shared by loop and merge detection (ORB-SLAM3's
//! `LoopClosing::NewDetectCommonRegions`: `mnLoopNumCoincidences` /
//! `mnLoopNumNotFound` for loops, `mnMergeNumCoincidences` /
//! `mnMergeNumNotFound` for merges): a verified candidate waits for enough
//! confirmations from the keyframes that follow; a confirmation clears the
//! misses, and `max_misses` misses in a row end the streak.

/// A candidate (`subject`) and its confirmations so far.
#[derive(Debug, Clone)]
pub(crate) struct CandidateStreak<T> {
    /// What is being confirmed (a loop's candidate and correction, or a
    /// merge's target map).
    pub(crate) subject: T,
    confirmations: usize,
    misses: usize,
}

impl<T> CandidateStreak<T> {
    /// A streak that starts with `confirmations`.
    pub(crate) fn start(subject: T, confirmations: usize) -> Self {
        Self {
            subject,
            confirmations,
            misses: 0,
        }
    }

    /// The confirmations so far.
    pub(crate) fn confirmations(&self) -> usize {
        self.confirmations
    }

    /// Adds `count` confirmations (the misses start over) and returns the
    /// total.
    pub(crate) fn confirm(&mut self, count: usize) -> usize {
        self.confirmations += count;
        self.misses = 0;
        self.confirmations
    }

    /// A keyframe that did not confirm it; `true` when that makes
    /// `max_misses` in a row (the streak ends).
    pub(crate) fn miss(&mut self, max_misses: usize) -> bool {
        self.misses += 1;
        self.misses >= max_misses
    }
}

#[cfg(test)]
mod tests {
    use super::CandidateStreak;

    #[test]
    fn misses_in_a_row_end_it_and_a_confirmation_starts_them_over() {
        let mut streak = CandidateStreak::start("candidate", 1);
        assert!(!streak.miss(2));
        assert_eq!(streak.confirm(1), 2);
        assert!(!streak.miss(2), "the earlier miss was cleared");
        assert!(streak.miss(2));
        assert_eq!(streak.confirmations(), 2);
        assert_eq!(streak.subject, "candidate");
    }
}
