//! Synthetic stereo sequences with exact ground truth: a world of textured
//! planes (a city block, a street, a ring corridor, an open highway with
//! its texture mostly far away, a street with two look-alike places)
//! ray-cast from a rectified stereo camera along a trajectory, with depth
//! for RGB-D, and hard conditions (light changes, low light, bare or repeated
//! façades, a fast turn in place, a kidnap by black frames or by a jump).
//!
//! Everything is a pure function of [`SyntheticConfig`] (its seed
//! included): the same config writes byte-identical files.
//!
//! ```no_run
//! use spslam::dataset::synthetic::{write_sequence, SceneName, SyntheticConfig, SyntheticSequence, WriteOptions};
//! let sequence = SyntheticSequence::new(SyntheticConfig::for_scene(SceneName::Loop))?;
//! let frame = sequence.render(10, true); // left, right, depth, pose
//! write_sequence(&sequence, "/tmp/synth".as_ref(), &WriteOptions::default(), &mut |_, _| {})?;
//! # Ok::<(), spslam::dataset::synthetic::SyntheticError>(())
//! ```
//!
//! Conventions: KITTI's camera frame (x right, y down, z forward); poses
//! are T_wc of the left camera with the first pose the identity; the right
//! camera sits `baseline` metres along the left's x axis; pixel centres
//! lie on integer coordinates.

mod camera;
mod conditions;
mod config;
mod error;
mod manoeuvre;
mod noise;
mod render;
mod rng;
mod scenes;
mod sequence;
mod styles;
mod texture;
mod trajectory;
mod world;
mod writer;

pub use camera::StereoCamera;
pub use conditions::{Condition, Photometry, BLACKOUT_FRAMES};
pub use config::{SceneName, SyntheticConfig};
pub use error::{Result, SyntheticError};
pub use manoeuvre::{Manoeuvre, TURN_IN_PLACE_FRAMES};
pub use render::{render_view, View};
pub use rng::SplitMix64;
pub use scenes::{build_scene, AliasingLayout, Scene, ALIASING_LAYOUT};
pub use sequence::{SyntheticFrame, SyntheticSequence};
pub use texture::{DiscMarker, Footprint, ProceduralTexture, ShapeKind, ShapeLayer, Texture};
pub use trajectory::{PathShape, Trajectory, Wobble};
pub use world::{Hit, Plane, Skyline, World};
pub use writer::{write_sequence, WriteOptions, WrittenSequence, DEPTH_UNITS_PER_METRE};
