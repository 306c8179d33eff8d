//! Observations of a 3-D point: the measured pixel(s) and their information weight.

use nalgebra::{Vector2, Vector3};

use super::robust::{CHI2_MONO_95, CHI2_STEREO_95};

/// What was measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Measurement {
    /// A left-image keypoint `(u, v)`.
    Mono(Vector2<f64>),
    /// A stereo keypoint `(u, v, u_right)`.
    Stereo(Vector3<f64>),
}

/// One observation: a measurement and its isotropic information weight
/// `1/σ²` (ORB-SLAM3's `mvInvLevelSigma2[octave]`, see [`inv_level_sigma2`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    /// The measured pixel(s).
    pub measurement: Measurement,
    /// The information weight `1/σ²` applied to every residual component.
    pub information: f64,
}

/// ORB-SLAM3's inverse level variance: `1 / scale_factor^(2·octave)`.
pub fn inv_level_sigma2(scale_factor: f64, octave: u32) -> f64 {
    1.0 / scale_factor.powi(2 * octave as i32)
}

impl Observation {
    /// A monocular observation `(u, v)` with information `1/σ²`.
    pub fn mono(u: f64, v: f64, information: f64) -> Self {
        Self {
            measurement: Measurement::Mono(Vector2::new(u, v)),
            information,
        }
    }

    /// A stereo observation `(u, v, u_right)` with information `1/σ²`.
    pub fn stereo(u: f64, v: f64, u_right: f64, information: f64) -> Self {
        Self {
            measurement: Measurement::Stereo(Vector3::new(u, v, u_right)),
            information,
        }
    }

    /// True for a stereo observation.
    pub fn is_stereo(&self) -> bool {
        matches!(self.measurement, Measurement::Stereo(_))
    }

    /// ORB-SLAM3's 95 % χ² outlier threshold: 5.991 (2 dof) or 7.815 (3 dof).
    pub fn chi2_threshold(&self) -> f64 {
        if self.is_stereo() {
            CHI2_STEREO_95
        } else {
            CHI2_MONO_95
        }
    }

    /// ORB-SLAM3's Huber delta: the square root of [`Observation::chi2_threshold`].
    pub fn huber_delta(&self) -> f64 {
        self.chi2_threshold().sqrt()
    }

    /// `information · |residual|²` against a predicted stereo projection
    /// `(u, v, u_right)` ([`super::PinholeStereo::project_stereo`]): all
    /// three components for a stereo observation, `(u, v)` for a monocular
    /// one.
    pub fn chi2_of_prediction(&self, predicted: &Vector3<f64>) -> f64 {
        let err2 = match &self.measurement {
            Measurement::Mono(m) => (predicted.x - m.x).powi(2) + (predicted.y - m.y).powi(2),
            Measurement::Stereo(m) => (predicted - m).norm_squared(),
        };
        self.information * err2
    }

    /// Whether a predicted stereo projection is within this observation's
    /// 95 % χ² ([`Observation::chi2_threshold`]): ORB-SLAM3's test of a new
    /// point (`CreateNewMapPoints`) and of a fusion (`ORBmatcher::Fuse`).
    pub fn accepts_prediction(&self, predicted: &Vector3<f64>) -> bool {
        self.chi2_of_prediction(predicted) <= self.chi2_threshold()
    }

    /// True when the measurement is finite and the information positive and finite.
    pub fn is_valid(&self) -> bool {
        let finite = match &self.measurement {
            Measurement::Mono(m) => m.iter().all(|v| v.is_finite()),
            Measurement::Stereo(m) => m.iter().all(|v| v.is_finite()),
        };
        finite && self.information.is_finite() && self.information > 0.0
    }
}
