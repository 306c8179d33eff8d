//! # spslam
//!
//! SuperPoint-SLAM3 rebuilt in Rust. This crate ships:
//! - [`features`]: the SuperPoint + ANMS feature extractor (ONNX Runtime), with
//!   ORB-SLAM3's pyramid and scale-table semantics, and OpenCV's ORB as a reference;
//! - `ffi`: a C ABI over the extractor (see `include/spslam.h`);
//! - [`geometry`]: monocular two-view reconstruction (ORB-SLAM3's `TwoViewReconstruction`);
//! - the SLAM core, bottom up: [`map`], [`camera`], [`tracking`] and
//!   [`mapping`] (which never import each other's layers above), and
//!   [`system`], which drives them over an atlas of maps;
//! - [`place`]: place recognition below the system layer (VLAD codebooks,
//!   the keyframe database, the k-means and DBoW2 vocabulary training
//!   behind `spslam vocab train`);
//! - [`loop_closing`]: loop and merge detection, verification and
//!   correction, the global BA;
//! - [`storage`]: map files (save, load, checks).
#![warn(missing_docs)]

pub mod camera;
pub mod dataset;
pub mod error;
pub mod eval;
pub mod features;
pub mod ffi;
pub mod geometry;
pub mod loop_closing;
pub mod map;
pub mod mapping;
pub mod matching;
pub mod optim;
pub mod place;
pub mod settings;
pub mod stats;
pub mod storage;
pub mod system;
pub mod tracking;

#[cfg(test)]
mod test_world;
