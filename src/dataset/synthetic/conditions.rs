//! Hard imaging conditions for a synthetic sequence: light that changes
//! (a ramp, flicker, a second lap at dusk), low light with shot and read
//! noise, a kidnap (black frames), façades with low or repeated texture,
//! and two changes of the motion (a fast turn in place, a kidnap by a jump
//! back). The ground truth stays exact: the images change, or the path is
//! re-timed by a [`Manoeuvre`] that the poses follow.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use super::manoeuvre::{Manoeuvre, TURN_IN_PLACE_FRAMES};
use super::rng::{mix64, unit_from_bits};
use super::styles::Facades;

/// A hard condition applied to a sequence's images or motion.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Condition {
    /// None: the scene's own light.
    #[default]
    Normal,
    /// Evening comes: the gain falls linearly from 1 to 0.4 and the gamma
    /// rises from 1 to 1.5 over the sequence.
    LightRamp,
    /// Flicker: each frame's gain is drawn at random in [0.6, 1.4]
    /// (a lamp beating against the shutter), independently per frame.
    Flicker,
    /// The second lap at dusk: from the frame that starts the second lap
    /// (the middle frame for a scene without laps) the gain is 0.35 with
    /// gamma 1.3, shot noise and read noise (σ 3 gray levels). Loops must
    /// be closed across the change.
    Dusk,
    /// Low light throughout: gain 0.25, shot noise and read noise
    /// (σ 3 gray levels).
    LowLight,
    /// A kidnap: eight black frames in the middle of the sequence while the
    /// camera goes on moving; tracking must be lost and found again.
    Blackout,
    /// Low texture: the façades are mostly bare plaster (three quarters of
    /// 5-m zones without detail, sparse windows and panels).
    LowTexture,
    /// Repeated texture: every façade shows the same periodic grid of
    /// identical windows and panels.
    RepeatedTexture,
    /// Fast rotation: in the middle of the sequence the camera stops and
    /// turns once round in place over [`TURN_IN_PLACE_FRAMES`] frames (up
    /// to 20° per frame), then drives on.
    TurnInPlace,
    /// A kidnap by a jump: in the middle of the sequence the camera is
    /// carried back a quarter of the sequence's path to a place it has
    /// seen, and drives on from there; tracking must relocalise in the map.
    JumpBack,
}

impl Condition {
    /// All conditions, in the order they are documented.
    pub const ALL: [Condition; 10] = [
        Condition::Normal,
        Condition::LightRamp,
        Condition::Flicker,
        Condition::Dusk,
        Condition::LowLight,
        Condition::Blackout,
        Condition::LowTexture,
        Condition::RepeatedTexture,
        Condition::TurnInPlace,
        Condition::JumpBack,
    ];

    /// The name used on the command line.
    pub fn as_str(&self) -> &'static str {
        match self {
            Condition::Normal => "normal",
            Condition::LightRamp => "light-ramp",
            Condition::Flicker => "flicker",
            Condition::Dusk => "dusk",
            Condition::LowLight => "low-light",
            Condition::Blackout => "blackout",
            Condition::LowTexture => "low-texture",
            Condition::RepeatedTexture => "repeated-texture",
            Condition::TurnInPlace => "turn-in-place",
            Condition::JumpBack => "jump-back",
        }
    }

    /// How the scene's façades look under this condition.
    pub fn facades(&self) -> Facades {
        match self {
            Condition::LowTexture => Facades::Bare,
            Condition::RepeatedTexture => Facades::Repeated,
            _ => Facades::Varied,
        }
    }

    /// The change of the camera's motion under this condition, for a
    /// scene of `frames` frames without it (placed in their middle).
    pub fn manoeuvre(&self, frames: usize) -> Option<Manoeuvre> {
        let at = frames / 2;
        match self {
            Condition::TurnInPlace => Some(Manoeuvre::TurnInPlace {
                at,
                frames: TURN_IN_PLACE_FRAMES,
            }),
            Condition::JumpBack => Some(Manoeuvre::JumpBack {
                at,
                frames: frames / 4,
            }),
            _ => None,
        }
    }
}

impl fmt::Display for Condition {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for Condition {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Condition::ALL
            .into_iter()
            .find(|c| c.as_str().eq_ignore_ascii_case(s))
            .ok_or_else(|| {
                let names: Vec<&str> = Condition::ALL.iter().map(Condition::as_str).collect();
                format!("unknown condition `{s}`; expected {}", names.join(", "))
            })
    }
}

/// Number of black frames of a [`Condition::Blackout`].
pub const BLACKOUT_FRAMES: usize = 8;

/// What a condition does to one frame's image: `out = 255 · (gain ·
/// in / 255)^gamma`, then shot noise of variance `shot · out` and read
/// noise of deviation `read_sigma` (gray levels); `black` blanks the image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Photometry {
    /// Multiplies the linear intensity.
    pub gain: f64,
    /// Exponent of the response curve (1: linear).
    pub gamma: f64,
    /// Shot-noise variance per gray level of signal (0: none).
    pub shot: f64,
    /// Read-noise standard deviation (gray levels).
    pub read_sigma: f64,
    /// The frame is black (a kidnap).
    pub black: bool,
}

impl Photometry {
    /// No change.
    pub const IDENTITY: Photometry = Photometry {
        gain: 1.0,
        gamma: 1.0,
        shot: 0.0,
        read_sigma: 0.0,
        black: false,
    };

    /// The response curve, before noise.
    pub fn apply(&self, value: f64) -> f64 {
        if self.black {
            return 0.0;
        }
        let linear = (self.gain * value / 255.0).max(0.0);
        255.0 * linear.powf(self.gamma)
    }

    /// The noise's standard deviation at a (response-curved) value.
    pub fn noise_sigma(&self, value: f64) -> f64 {
        if self.black {
            return 0.0;
        }
        (self.shot * value.max(0.0) + self.read_sigma * self.read_sigma).sqrt()
    }
}

/// The dark settings shared by dusk and low light.
fn dark(gain: f64, gamma: f64) -> Photometry {
    Photometry {
        gain,
        gamma,
        shot: 0.5,
        read_sigma: 3.0,
        black: false,
    }
}

impl Condition {
    /// The photometry of frame `index` of `frames`; `lap_frames` is the
    /// length of a lap when the path is a loop.
    pub fn photometry(
        &self,
        index: usize,
        frames: usize,
        lap_frames: Option<usize>,
        seed: u64,
    ) -> Photometry {
        let middle = frames / 2;
        match self {
            Condition::Normal
            | Condition::LowTexture
            | Condition::RepeatedTexture
            | Condition::TurnInPlace
            | Condition::JumpBack => Photometry::IDENTITY,
            Condition::LightRamp => {
                let t = index as f64 / (frames.max(2) - 1) as f64;
                Photometry {
                    gain: 1.0 - 0.6 * t,
                    gamma: 1.0 + 0.5 * t,
                    ..Photometry::IDENTITY
                }
            }
            Condition::Flicker => {
                let bits =
                    mix64(seed ^ 0x0066_6c69_636b_6572 ^ (index as u64).wrapping_mul(0x9e37));
                Photometry {
                    gain: 0.6 + 0.8 * unit_from_bits(bits),
                    ..Photometry::IDENTITY
                }
            }
            Condition::Dusk => {
                let start = lap_frames
                    .filter(|&l| l > 0 && l < frames)
                    .unwrap_or(middle);
                if index >= start {
                    dark(0.35, 1.3)
                } else {
                    Photometry::IDENTITY
                }
            }
            Condition::LowLight => dark(0.25, 1.0),
            Condition::Blackout => Photometry {
                black: (middle..middle + BLACKOUT_FRAMES).contains(&index),
                ..Photometry::IDENTITY
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_unknown_names_list_the_choices() {
        for c in Condition::ALL {
            assert_eq!(c.to_string().parse::<Condition>(), Ok(c));
        }
        let err = "fog".parse::<Condition>().unwrap_err();
        assert!(
            err.contains("light-ramp") && err.contains("blackout"),
            "{err}"
        );
    }

    #[test]
    fn each_condition_changes_the_frames_it_should() {
        let p = |c: Condition, i: usize| c.photometry(i, 100, Some(60), 7);
        assert_eq!(p(Condition::Normal, 50), Photometry::IDENTITY);
        // The ramp darkens monotonically to 0.4 × with gamma 1.5.
        let (first, last) = (p(Condition::LightRamp, 0), p(Condition::LightRamp, 99));
        assert_eq!((first.gain, first.gamma), (1.0, 1.0));
        assert!((last.gain - 0.4).abs() < 1e-12 && (last.gamma - 1.5).abs() < 1e-12);
        // Flicker: different gains in [0.6, 1.4], the same for the same frame.
        let gains: Vec<f64> = (0..50).map(|i| p(Condition::Flicker, i).gain).collect();
        assert!(gains.iter().all(|g| (0.6..=1.4).contains(g)));
        assert!(gains.iter().any(|g| *g < 0.8) && gains.iter().any(|g| *g > 1.2));
        assert_eq!(p(Condition::Flicker, 3), p(Condition::Flicker, 3));
        // Dusk starts at the second lap (or the middle without laps).
        assert_eq!(p(Condition::Dusk, 59), Photometry::IDENTITY);
        assert!(p(Condition::Dusk, 60).gain < 0.5);
        assert!(Condition::Dusk.photometry(49, 100, None, 7).gain == 1.0);
        assert!(Condition::Dusk.photometry(50, 100, None, 7).gain < 0.5);
        // Blackout: exactly BLACKOUT_FRAMES black frames from the middle.
        let black: Vec<usize> = (0..100)
            .filter(|&i| p(Condition::Blackout, i).black)
            .collect();
        assert_eq!(black, (50..50 + BLACKOUT_FRAMES).collect::<Vec<_>>());
    }

    #[test]
    fn low_light_is_dark_and_noisy() {
        let dark = Condition::LowLight.photometry(0, 10, None, 0);
        assert!((dark.apply(200.0) - 50.0).abs() < 1e-9);
        // Shot noise grows with the signal; read noise stays in the dark.
        assert!((dark.noise_sigma(0.0) - 3.0).abs() < 1e-12);
        assert!(dark.noise_sigma(50.0) > 5.0);
        let black = Condition::Blackout.photometry(5, 10, None, 0);
        assert_eq!((black.apply(200.0), black.noise_sigma(200.0)), (0.0, 0.0));
    }
}
