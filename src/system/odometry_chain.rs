//! Lost frames given a pose by chains of odometry steps.
//!
//! A lost stereo or RGB-D frame's record may hold its motion from the
//! input frame before it, measured by odometry (`FrameRecord::gap_step`;
//! see `crate::tracking`'s gap odometry). Two consecutive records are
//! *linked* when the later one holds such a step. A lost frame linked, step
//! by step, to a frame with a pose (tracked live, localised after the
//! fact, or itself chained) has a pose too: forwards from the last tracked
//! frame, or backwards from the next frame with a pose (the first frame of
//! a blurred turn rarely matches the sharp frame before it, but the
//! blurred frames match each other and the first frame tracking resumes
//! on). Its record gets [`TrackingMethod::Odometry`] and says `Ok`; the
//! trajectory places it along the chain ([`super::trajectory`]).
//!
//! This is the one place that decides which lost frames odometry poses:
//! every record that gains a pose is passed here.

use crate::tracking::{TrackingMethod, TrackingState};

use super::records::FrameRecord;

/// Whether records `k` and `k + 1` are consecutive input frames joined by
/// the step the later one measured.
pub(super) fn linked(records: &[FrameRecord], k: usize) -> bool {
    match (records.get(k), records.get(k + 1)) {
        (Some(earlier), Some(later)) => {
            later.gap_step.is_some()
                && later.index == earlier.index + 1
                && earlier.unreadable.is_none()
        }
        _ => false,
    }
}

/// Whether a record has a pose (its state is `Ok`).
fn posed(record: &FrameRecord) -> bool {
    record.state == TrackingState::Ok
}

/// Whether a record without a pose may take one from a chain.
fn chainable(record: &FrameRecord) -> bool {
    !posed(record) && record.method == TrackingMethod::None && record.unreadable.is_none()
}

/// Marks a record as posed by odometry.
fn mark(record: &mut FrameRecord) {
    record.state = TrackingState::Ok;
    record.method = TrackingMethod::Odometry;
}

/// Record `at` has just been written or given a pose: when it has a pose,
/// or is linked to the record before it and that one has, its pose spreads
/// along the links to every lost record they reach, backwards and
/// forwards. Returns how many records it gave a pose.
pub(super) fn chain_odometry(records: &mut [FrameRecord], at: usize) -> usize {
    let Some(record) = records.get(at) else {
        return 0;
    };
    let mut marked = 0;
    if !posed(record) {
        let joined = at > 0 && linked(records, at - 1) && posed(&records[at - 1]);
        if !(joined && chainable(record)) {
            return 0;
        }
        mark(&mut records[at]);
        marked += 1;
    }
    let mut k = at;
    while k > 0 && linked(records, k - 1) && chainable(&records[k - 1]) {
        mark(&mut records[k - 1]);
        marked += 1;
        k -= 1;
    }
    let mut k = at;
    while linked(records, k) && chainable(&records[k + 1]) {
        mark(&mut records[k + 1]);
        marked += 1;
        k += 1;
    }
    marked
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optim::{LieGroup, Se3};

    /// Records of frames 0..n: `posed[i]` tracked, else lost; `step[i]`
    /// frame i measured its step from frame i − 1.
    fn records(posed: &[bool], step: &[bool]) -> Vec<FrameRecord> {
        posed
            .iter()
            .zip(step)
            .enumerate()
            .map(|(index, (&posed, &step))| FrameRecord {
                index,
                timestamp: index as f64 * 0.1,
                state: if posed {
                    TrackingState::Ok
                } else {
                    TrackingState::Lost
                },
                method: if posed {
                    TrackingMethod::MotionModel
                } else {
                    TrackingMethod::None
                },
                map: 0,
                inliers: 0,
                stereo_points: 0,
                keyframe: false,
                unreadable: None,
                relative_pose: None,
                gap_rotation: None,
                gap_rotation_deg: None,
                gap_step: step.then(Se3::identity),
                gap_step_inliers: None,
                timings: Default::default(),
                mapping: None,
                loop_check_running: false,
                second_look: None,
            })
            .collect()
    }

    fn methods(records: &[FrameRecord]) -> String {
        records
            .iter()
            .map(|r| match r.method {
                TrackingMethod::Odometry => 'o',
                TrackingMethod::None => '-',
                _ => 'T',
            })
            .collect()
    }

    /// Writes the records one by one, as a run does.
    fn replay(mut all: Vec<FrameRecord>) -> Vec<FrameRecord> {
        let full = all.clone();
        all.clear();
        for record in full {
            all.push(record);
            let at = all.len() - 1;
            chain_odometry(&mut all, at);
        }
        all
    }

    #[test]
    fn steps_carry_a_pose_forwards_until_a_link_is_missing() {
        let posed = [true, false, false, false, false];
        let step = [false, true, true, false, true];
        let out = replay(records(&posed, &step));
        assert_eq!(methods(&out), "Too--");
        assert!(out[1..3].iter().all(|r| r.state == TrackingState::Ok));
        assert_eq!(out[3].state, TrackingState::Lost);
    }

    #[test]
    fn a_frame_with_a_pose_carries_it_backwards_over_the_linked_lost_frames() {
        // Frame 1 did not match frame 0 (the first blurred frame of a turn);
        // frames 1–3 match each other and frame 4, where tracking resumed.
        let posed = [true, false, false, false, true, true];
        let step = [false, false, true, true, true, false];
        let out = replay(records(&posed, &step));
        assert_eq!(methods(&out), "ToooTT");
    }

    #[test]
    fn a_pose_given_late_spreads_both_ways_and_unlinked_frames_stay_lost() {
        let posed = [true, false, false, false, false, false, false];
        let step = [false, false, true, false, true, true, false];
        let mut out = replay(records(&posed, &step));
        assert_eq!(methods(&out), "T------");
        // Frame 4 localised after the fact: 3 (by 4's step) and 5 (by 5's).
        out[4].state = TrackingState::Ok;
        out[4].method = TrackingMethod::AfterLoss;
        assert_eq!(chain_odometry(&mut out, 4), 2);
        assert_eq!(methods(&out), "T--oTo-");
        // An unreadable frame breaks a chain.
        let mut out = replay(records(&[true, false, false], &[false, true, true]));
        assert_eq!(methods(&out), "Too");
        out = records(&[true, false, false], &[false, true, true]);
        out[1].unreadable = Some("missing".into());
        out[1].gap_step = None;
        assert_eq!(chain_odometry(&mut out, 0), 0);
        assert_eq!(methods(&out), "T--");
    }
}
