//! The bundle-adjustment problem in flat arrays, and its validation.

use nalgebra::Vector3;

use crate::optim::reprojection::{Observation, PinholeStereo};
use crate::optim::{OptimError, Se3};

/// One observation of point `point` from keyframe pose `pose`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BaObservation {
    /// Index into [`BundleProblem::poses`].
    pub pose: usize,
    /// Index into [`BundleProblem::points`].
    pub point: usize,
    /// The measurement and its information weight.
    pub obs: Observation,
}

/// A local bundle-adjustment problem: keyframe poses `T_cw` (some fixed),
/// world points and their observations, all by index.
#[derive(Debug, Clone, PartialEq)]
pub struct BundleProblem {
    /// The camera shared by every keyframe.
    pub camera: PinholeStereo,
    /// Keyframe poses `T_cw`; optimised in place.
    pub poses: Vec<Se3>,
    /// Per pose: true to hold it fixed (it stays bit-identical).
    pub fixed: Vec<bool>,
    /// World points; all optimised in place.
    pub points: Vec<Vector3<f64>>,
    /// The observations.
    pub observations: Vec<BaObservation>,
}

fn se3_is_finite(pose: &Se3) -> bool {
    pose.translation.iter().all(|v| v.is_finite())
        && pose.rotation.coords.iter().all(|v| v.is_finite())
}

impl BundleProblem {
    /// Checks sizes, indices and values; the first problem found is the error.
    pub fn validate(&self) -> Result<(), OptimError> {
        if !self.camera.is_valid() {
            return Err(OptimError::InvalidValue {
                what: "camera",
                index: 0,
            });
        }
        if self.fixed.len() != self.poses.len() {
            return Err(OptimError::FixedFlagsLength {
                flags: self.fixed.len(),
                poses: self.poses.len(),
            });
        }
        if let Some(index) = self.poses.iter().position(|p| !se3_is_finite(p)) {
            return Err(OptimError::InvalidValue {
                what: "pose",
                index,
            });
        }
        if let Some(index) = self
            .points
            .iter()
            .position(|p| !p.iter().all(|v| v.is_finite()))
        {
            return Err(OptimError::InvalidValue {
                what: "point",
                index,
            });
        }
        if self.observations.is_empty() {
            return Err(OptimError::NoObservations);
        }
        for (observation, o) in self.observations.iter().enumerate() {
            if o.pose >= self.poses.len() {
                return Err(OptimError::PoseIndexOutOfRange {
                    observation,
                    pose: o.pose,
                    poses: self.poses.len(),
                });
            }
            if o.point >= self.points.len() {
                return Err(OptimError::PointIndexOutOfRange {
                    observation,
                    point: o.point,
                    points: self.points.len(),
                });
            }
            if !o.obs.is_valid() {
                return Err(OptimError::InvalidValue {
                    what: "observation",
                    index: observation,
                });
            }
        }
        if self.observations.len() > u32::MAX as usize || self.poses.len() >= u32::MAX as usize {
            return Err(OptimError::InvalidOption {
                option: "problem size (observations or poses beyond u32)",
                value: self.observations.len() as f64,
            });
        }
        Ok(())
    }
}
