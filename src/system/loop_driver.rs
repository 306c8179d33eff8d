//! How [`SlamSystem`] drives loop closing: the keyframes local mapping has
//! processed go to the stage (inline) or to the loop-closing thread; what
//! either finds is corrected here, between frames, with local mapping
//! paused: a loop ([`LoopClosingStage::correct`]) or a merge of the active
//! map into an older one ([`LoopClosingStage::merge`], after which the
//! older map is active and the frame records follow it).

use std::sync::Arc;

use crate::error::SlamError;
use crate::loop_closing::{DatabaseRelocaliser, LoopThresholds};
use crate::place::GlobalDescriptor;

use super::atlas::MapIndex;
use super::loop_closing_stage::{
    Detection, LoopCandidateRecord, LoopClosingStage, LoopRecord, MergeRecord, RejectedLoopRecord,
};
use super::loop_closing_thread::{AtlasView, LoopClosingThread, LoopFinding};
use super::slam_system::{LoopClosing, Mapping};
use super::SlamSystem;

impl SlamSystem {
    /// Switches loop closing on, with `descriptor` for place recognition
    /// (a VLAD codebook, see [`crate::place::Codebook`]). Keyframes made
    /// before this call are not checked. With a local-mapping thread
    /// ([`Self::spawn_mapping_thread`]) the check runs on its own thread.
    ///
    /// Relocalisation then asks the same keyframe database for its
    /// candidates ([`DatabaseRelocaliser`], as ORB-SLAM3's
    /// `DetectRelocalizationCandidates`) instead of scanning the newest
    /// keyframes; keyframes made before this call are not in it. The
    /// tracker keeps the source over a reset or a new map, and the stage
    /// empties the database in place on either.
    pub fn enable_loop_closing(
        &mut self,
        descriptor: Arc<dyn GlobalDescriptor>,
        thresholds: LoopThresholds,
    ) -> Result<(), SlamError> {
        self.loop_log.keep_candidates = thresholds.record_every_stage;
        let stage = LoopClosingStage::new(Arc::clone(&descriptor), thresholds)?;
        let relocaliser = DatabaseRelocaliser::new(descriptor, stage.shared_database());
        self.tracker
            .set_relocalisation_candidates(Some(Arc::new(relocaliser)));
        self.loop_inbox.clear();
        self.loop_closing = Some(LoopClosing::Inline(Box::new(stage)));
        if matches!(self.mapping, Mapping::Thread { .. }) {
            self.spawn_loop_closing_thread()?;
        }
        Ok(())
    }

    /// The loops accepted and corrected so far.
    pub fn loops(&self) -> &[LoopRecord] {
        &self.loop_log.loops
    }

    /// The merges of the active map into an older one so far.
    pub fn merges(&self) -> &[MergeRecord] {
        &self.loop_log.merges
    }

    /// The loop and merge candidates that passed the descriptor stage and
    /// were rejected later.
    pub fn rejected_loops(&self) -> &[RejectedLoopRecord] {
        &self.loop_log.rejected
    }

    /// Every loop and merge candidate checked so far, with what each stage
    /// of its check counted (kept only with
    /// [`LoopThresholds::record_every_stage`]; empty otherwise).
    pub fn loop_candidates(&self) -> &[LoopCandidateRecord] {
        &self.loop_log.candidates
    }

    /// The active map and the maps it may merge with.
    fn atlas_view(&self) -> AtlasView {
        AtlasView {
            active: self.atlas.active().map.clone(),
            others: self
                .atlas
                .mergeable()
                .map(|m| (m.index, m.map.clone()))
                .collect(),
        }
    }

    /// The stage when loop closing runs inline.
    pub(super) fn inline_loop_stage(&mut self) -> Option<&mut LoopClosingStage> {
        match self.loop_closing.as_mut() {
            Some(LoopClosing::Inline(stage)) => Some(stage),
            _ => None,
        }
    }

    /// Moves inline loop closing to its own thread (no-op otherwise).
    pub(super) fn spawn_loop_closing_thread(&mut self) -> Result<(), SlamError> {
        let Some(LoopClosing::Inline(_)) = self.loop_closing else {
            return Ok(());
        };
        let view = self.atlas_view();
        let Some(LoopClosing::Inline(mut stage)) = self.loop_closing.take() else {
            return Ok(());
        };
        for kf in self.loop_inbox.drain(..) {
            stage.push(kf);
        }
        let thread = LoopClosingThread::spawn(*stage, self.rig, view)?;
        self.loop_closing = Some(LoopClosing::Thread(thread));
        Ok(())
    }

    /// Brings loop closing back inline: the thread checks what it has
    /// received, and what it found is corrected.
    pub(super) fn stop_loop_closing_thread(&mut self) -> Result<(), SlamError> {
        let Some(LoopClosing::Thread(_)) = self.loop_closing else {
            return Ok(());
        };
        let Some(LoopClosing::Thread(thread)) = self.loop_closing.take() else {
            return Ok(());
        };
        let (mut stage, findings) = thread.finish()?;
        let applied = findings
            .into_iter()
            .try_for_each(|f| self.apply_finding(&mut stage, f));
        self.loop_closing = Some(LoopClosing::Inline(Box::new(stage)));
        applied
    }

    /// Hands the keyframes local mapping has processed to loop closing and
    /// corrects the map with what it found.
    pub(super) fn close_loops(&mut self) -> Result<(), SlamError> {
        match self.loop_closing.take() {
            None => {
                self.loop_inbox.clear();
                Ok(())
            }
            Some(LoopClosing::Inline(mut stage)) => {
                let closed = self.close_inline(&mut stage);
                self.loop_closing = Some(LoopClosing::Inline(stage));
                closed
            }
            Some(LoopClosing::Thread(thread)) => self.close_threaded(thread),
        }
    }

    /// Checks every queued keyframe now and corrects what is accepted.
    fn close_inline(&mut self, stage: &mut LoopClosingStage) -> Result<(), SlamError> {
        loop {
            for kf in self.loop_inbox.drain(..) {
                stage.push(kf);
            }
            if !stage.has_queued() {
                return Ok(());
            }
            let view = self.atlas_view();
            let step = stage.detect_next(&view.active, &view.others, &self.rig)?;
            self.loop_log.record(step.rejected, step.candidates);
            if let Some(detection) = step.detection {
                self.apply_detection(stage, detection, &view)?;
            }
        }
    }

    /// Submits the new keyframes to the thread and, when it found
    /// something, takes the stage back, corrects, and restarts it.
    fn close_threaded(&mut self, mut thread: LoopClosingThread) -> Result<(), SlamError> {
        let view = self.atlas_view();
        for kf in std::mem::take(&mut self.loop_inbox) {
            thread.submit(kf, view.clone())?;
        }
        let findings = thread.poll()?;
        if !findings.iter().any(LoopFinding::needs_stage) {
            for finding in findings {
                if let Ok(step) = finding.step {
                    self.loop_log.record(step.rejected, step.candidates);
                }
            }
            self.loop_closing = Some(LoopClosing::Thread(thread));
            return Ok(());
        }
        let (mut stage, later) = thread.finish()?;
        for finding in findings.into_iter().chain(later) {
            self.apply_finding(&mut stage, finding)?;
        }
        // Keyframes mapped while local mapping was paused.
        for kf in self.loop_inbox.drain(..) {
            stage.push(kf);
        }
        let thread = LoopClosingThread::spawn(stage, self.rig, self.atlas_view())?;
        self.loop_closing = Some(LoopClosing::Thread(thread));
        Ok(())
    }

    /// Records a finding of the thread and corrects what it accepted.
    fn apply_finding(
        &mut self,
        stage: &mut LoopClosingStage,
        finding: LoopFinding,
    ) -> Result<(), SlamError> {
        let step = finding.step?;
        self.loop_log.record(step.rejected, step.candidates);
        match step.detection {
            Some(detection) => self.apply_detection(stage, detection, &finding.maps),
            None => Ok(()),
        }
    }

    /// Corrects a loop or carries out a merge found on the maps of `view`,
    /// with local mapping paused and any global BA aborted; then starts a
    /// global BA of the corrected map. A detection made on a map that is no
    /// longer active, or whose keyframes were culled since, is dropped.
    fn apply_detection(
        &mut self,
        stage: &mut LoopClosingStage,
        detection: Detection,
        view: &AtlasView,
    ) -> Result<(), SlamError> {
        if !Arc::ptr_eq(&view.active, &self.atlas.active().map) {
            tracing::warn!("a loop found on a map no longer active was dropped");
            return Ok(());
        }
        // A running global BA works on poses the correction replaces.
        self.abort_global_ba();
        self.pause_mapping()?;
        let corrected = match detection {
            Detection::Loop(accepted) => {
                match stage.correct(&view.active, &accepted, &self.rig)? {
                    Some(record) => self.loop_log.loops.push(record),
                    None => tracing::warn!("a loop whose keyframes were culled was dropped"),
                }
                view.active.clone()
            }
            Detection::Merge(accepted) => {
                let target = view.others.get(&accepted.target).cloned().ok_or(
                    SlamError::UnknownAtlasMap {
                        map: accepted.target,
                    },
                )?;
                let active = self.atlas.active().index;
                match stage.merge(&view.active, active, &target, &accepted, &self.rig)? {
                    Some(record) => {
                        self.follow_merge(accepted.target, record.scale);
                        self.loop_log.merges.push(record);
                        target
                    }
                    None => {
                        tracing::warn!("a merge whose keyframes were culled was dropped");
                        view.active.clone()
                    }
                }
            }
        };
        self.resume_mapping(&corrected)?;
        self.start_global_ba(&corrected)
    }

    /// After the active map was absorbed into map `into`, its units scaled
    /// by `scale` (1 but for a monocular map): `into` becomes active, the
    /// records of the absorbed map's frames name it (their keyframe ids are
    /// unchanged, see [`super::Atlas`]) and their poses relative to their
    /// keyframes, like tracking's, are measured in `into`'s units.
    fn follow_merge(&mut self, into: MapIndex, scale: f64) {
        let Some(merged) = self.atlas.merge_active_into(into) else {
            return;
        };
        for record in &mut self.records {
            if record.map == merged {
                record.map = into;
            }
            if let Some(rel) = record.relative_pose.as_mut() {
                if rel.map == merged {
                    rel.map = into;
                    rel.pose.translation *= scale;
                }
            }
        }
        self.tracker.rescale(scale);
    }
}
