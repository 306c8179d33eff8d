//! Manoeuvres on top of a path: a fast turn in place, and a kidnap by a
//! jump back to a place already seen. Each maps a frame to the frame of
//! the path it shows and an extra yaw, so the ground truth stays exact.

use std::f64::consts::TAU;

/// Frames of a [`Manoeuvre::TurnInPlace`]'s full turn: 10° per frame on
/// average, 20° per frame at its fastest (200°/s at 10 frames per second).
pub const TURN_IN_PLACE_FRAMES: usize = 36;

/// A change of the camera's motion along its path.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Manoeuvre {
    /// At frame `at` the camera stops and turns once round to the right
    /// about the vertical over `frames` frames, then drives on. The
    /// angular speed rises and falls as `1 − cos`, so it is zero at both
    /// ends and twice the mean in the middle.
    TurnInPlace {
        /// The frame the turn starts at.
        at: usize,
        /// Frames the full turn takes.
        frames: usize,
    },
    /// From frame `at` on the camera shows the path `frames` frames back:
    /// carried back to a place it has already seen, with the heading it
    /// had there, it goes on from there.
    JumpBack {
        /// The first frame after the jump.
        at: usize,
        /// How many frames of path the jump goes back.
        frames: usize,
    },
}

impl Manoeuvre {
    /// Frames the manoeuvre adds to the sequence, so that the path still
    /// ends where it would without it.
    pub fn extra_frames(&self) -> usize {
        match *self {
            Manoeuvre::TurnInPlace { frames, .. } | Manoeuvre::JumpBack { frames, .. } => frames,
        }
    }

    /// The (fractional) path frame shown at `frame`, and the yaw added to
    /// the path's heading there (radians, turning right).
    pub fn warp(&self, frame: f64) -> (f64, f64) {
        match *self {
            Manoeuvre::TurnInPlace { at, frames } => {
                let (at, n) = (at as f64, frames.max(1) as f64);
                if frame <= at {
                    (frame, 0.0)
                } else if frame < at + n {
                    let u = (frame - at) / n;
                    (at, TAU * u - (TAU * u).sin())
                } else {
                    (frame - n, 0.0)
                }
            }
            // Half a frame before `at`, so that the sub-poses of a blurred
            // frame never straddle the jump.
            Manoeuvre::JumpBack { at, frames } => {
                if frame < at as f64 - 0.5 {
                    (frame, 0.0)
                } else {
                    (frame - frames as f64, 0.0)
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_turn_is_one_full_smooth_turn_in_place() {
        let turn = Manoeuvre::TurnInPlace { at: 10, frames: 36 };
        assert_eq!(turn.warp(10.0), (10.0, 0.0));
        assert_eq!(turn.warp(46.0), (10.0, 0.0));
        assert_eq!(turn.warp(50.0), (14.0, 0.0));
        // The angle at each frame of the turn, then the full turn (which
        // is the heading of the path again).
        let mut angles: Vec<f64> = (10..46).map(|f| turn.warp(f as f64).1).collect();
        angles.push(TAU);
        // Every frame of the turn stands at path frame 10.
        assert!((10..46).all(|f| turn.warp(f as f64).0 == 10.0));
        // Halfway round at the middle, and the whole turn just before the end.
        assert!((angles[18] - TAU / 2.0).abs() < 1e-12);
        assert!((turn.warp(45.999_999).1 - TAU).abs() < 1e-6);
        let steps: Vec<f64> = angles.windows(2).map(|w| w[1] - w[0]).collect();
        assert!(steps.iter().all(|s| *s >= 0.0), "always turning right");
        let fastest = steps.iter().copied().fold(0.0, f64::max);
        assert!(
            (fastest.to_degrees() - 20.0).abs() < 0.1,
            "{} deg",
            fastest.to_degrees()
        );
        assert!(steps[0].to_degrees() < 0.6 && steps[35].to_degrees() < 0.6);
    }

    #[test]
    fn the_jump_goes_back_and_the_path_goes_on() {
        let jump = Manoeuvre::JumpBack {
            at: 100,
            frames: 50,
        };
        assert_eq!(jump.warp(99.0), (99.0, 0.0));
        assert_eq!(jump.warp(99.4), (99.4, 0.0));
        assert_eq!(jump.warp(100.0), (50.0, 0.0));
        assert_eq!(jump.warp(149.0), (99.0, 0.0));
        assert_eq!(jump.extra_frames(), 50);
    }
}
