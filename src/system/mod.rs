//! The system layer: the driver that owns the threads and the atlas.
//!
//! - [`SlamSystem`]: the front end, tracking (on the caller's thread) and
//!   local mapping (inline or on its [`MappingThread`]) over an [`Atlas`];
//!   loss is never final: when relocalisation keeps failing, tracking
//!   starts a new map (see [`crate::tracking::RELOCALISATION_PATIENCE_S`]);
//!   loop closing checks every keyframe local mapping has processed and
//!   corrects the map with the loops it accepts (see [`crate::loop_closing`]);
//! - [`Atlas`]: every map of a run;
//! - [`FrameRecord`], [`SlamSummary`]: what a run reports.
//!
//! Layers: frame → features → tracking → map ← local mapping, loop closing. This module
//! sits above them all; nothing below imports from it.

mod assembly;
mod atlas;
mod gap_motion;
mod global_ba_driver;
mod global_ba_thread;
mod lagged_mapping;
mod local_mapping_thread;
mod loop_closing_stage;
mod loop_closing_thread;
mod loop_driver;
mod map_files;
mod odometry_chain;
mod records;
mod second_look;
mod slam_system;
mod trajectory;
mod view;
mod worker;

pub use assembly::{
    assemble_system, file_fingerprint, AssembledSystem, ExtractorKind, SystemOptions,
};
pub use atlas::{Atlas, AtlasMap, MapIndex};
pub use gap_motion::GAP_HORIZON_S;
pub use global_ba_thread::GlobalBaHook;
pub use local_mapping_thread::{MappingResult, MappingThread};
pub use loop_closing_stage::{LoopCandidateRecord, LoopRecord, MergeRecord, RejectedLoopRecord};
pub use map_files::{LoadedMapUse, MapProvenance};
pub use records::{FrameRecord, FrameTimings, MapSummary, RelativePose, SlamSummary};
pub use second_look::{FrontendFactory, SecondLook, SecondLookOutcome};
pub use slam_system::SlamSystem;
pub use view::{FrameView, KeyFrameView, MapView};
