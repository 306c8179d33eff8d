//! The second look at a frame tracking lost: its images extracted again on
//! a deeper pyramid ([`crate::settings::ExtractorSettings::second_look_levels_for`])
//! and tracked once more, from the tracker's state before the first try.
//!
//! Why: a run's pyramid is chosen for speed (one SuperPoint level with a
//! depth), and the frames it loses are the hard ones (motion blur at a
//! corner, a turn), where a coarser level sees sharper, larger structures.
//! Four levels on every frame cost 1.2–2.1× the extraction; the second look
//! pays only on the frames the run's pyramid loses. ORB-SLAM3 has no such
//! step: its ORB pyramid has eight levels on every frame.
//!
//! The second look's extractors are made on the first frame that needs
//! them, so that a run that never loses a frame holds no second network.

use std::time::Instant;

use serde::Serialize;

use crate::camera::CameraRig;
use crate::error::SlamError;
use crate::tracking::{Extractors, Frame, FrameBuilder, Frontend, SensorImages};

/// Makes the second look's front end: its extractors (on its pyramid) and
/// the frame builder for their scales.
pub type FrontendFactory = Box<dyn Fn() -> Result<Frontend, SlamError> + Send>;

/// What the second look at a lost frame gave.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SecondLookOutcome {
    /// The frame was tracked on the second look's features.
    Tracked,
    /// It was lost on those too: it keeps the first try's outcome and
    /// tracking state.
    StillLost,
}

/// A lost frame built again from the second look's features.
pub(super) struct SecondLookFrame {
    /// The frame (its keypoints on the second look's pyramid).
    pub frame: Frame,
    /// The extraction's wall time, ms.
    pub extraction_ms: f64,
    /// Stereo matching's (or the depth lookup's), ms.
    pub stereo_ms: f64,
}

/// The second look's front end, made when first needed.
pub struct SecondLook {
    levels: usize,
    make: FrontendFactory,
    parts: Option<(Extractors, FrameBuilder)>,
    /// Why they could not be made, once that failed: no second look after.
    failed: Option<String>,
}

impl SecondLook {
    /// A second look on `levels` pyramid levels, whose extractors `make` builds.
    pub fn new(levels: usize, make: FrontendFactory) -> Self {
        Self {
            levels,
            make,
            parts: None,
            failed: None,
        }
    }

    /// Its pyramid levels.
    pub fn levels(&self) -> usize {
        self.levels
    }

    /// Frame `index` built from its features on the second look's
    /// pyramid; `None` when the extractors could not be made (warned
    /// once) or the extraction failed (warned): the frame then keeps its
    /// first try.
    pub(super) fn frame(
        &mut self,
        index: usize,
        timestamp: f64,
        images: SensorImages<'_>,
        rig: &CameraRig,
    ) -> Result<Option<SecondLookFrame>, SlamError> {
        if self.failed.is_some() {
            return Ok(None);
        }
        // The first look's time includes loading the network.
        let start = Instant::now();
        if self.parts.is_none() {
            match (self.make)() {
                Ok(frontend) => self.parts = Some(frontend.into_parts()),
                Err(e) => {
                    tracing::warn!(
                        frame = index,
                        error = %e,
                        "the second look's extractors could not be made; lost frames get no second look"
                    );
                    self.failed = Some(e.to_string());
                    return Ok(None);
                }
            }
        }
        let Some((extractors, builder)) = self.parts.as_mut() else {
            return Ok(None);
        };
        let features = match extractors.extract(index, images) {
            Ok(features) => features,
            Err(e) => {
                tracing::warn!(frame = index, error = %e, "the second look's extraction failed");
                return Ok(None);
            }
        };
        let extraction_ms = start.elapsed().as_secs_f64() * 1e3;
        let (frame, stereo_ms) = builder.build_frame(index, timestamp, features, images, rig)?;
        Ok(Some(SecondLookFrame {
            frame,
            extraction_ms,
            stereo_ms,
        }))
    }
}

impl std::fmt::Debug for SecondLook {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SecondLook")
            .field("levels", &self.levels)
            .field("made", &self.parts.is_some())
            .field("failed", &self.failed)
            .finish()
    }
}
