//! What to generate: the scene, the camera, the motion and the image effects.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use super::conditions::Condition;
use super::error::{Result, SyntheticError};

/// The built-in scenes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SceneName {
    /// A street canyon around a city block, driven once around: the last
    /// frame is back at the first pose (loop closing).
    Loop,
    /// A straight street with buildings on both sides and side-street gaps.
    Straight,
    /// A hand-held camera (smooth random shake) walking a ring corridor.
    Wobbly,
    /// A car at highway speed on an open road: a few roadside signs,
    /// barriers and cabinets 5–15 m away, and most of the texture on
    /// buildings and hillsides 40–150 m from the road (stereo "far" points).
    Highway,
    /// Perceptual aliasing: a straight street that passes two look-alike
    /// places (the same façade textures at the same coordinates along the
    /// street) whose walls stand at different distances from the road, so
    /// that appearance says "loop" but geometry says "no".
    Aliasing,
}

impl SceneName {
    /// All scenes, in the order they are documented.
    pub const ALL: [SceneName; 5] = [
        SceneName::Loop,
        SceneName::Straight,
        SceneName::Wobbly,
        SceneName::Highway,
        SceneName::Aliasing,
    ];

    /// The lower-case name used on the command line.
    pub fn as_str(&self) -> &'static str {
        match self {
            SceneName::Loop => "loop",
            SceneName::Straight => "straight",
            SceneName::Wobbly => "wobbly",
            SceneName::Highway => "highway",
            SceneName::Aliasing => "aliasing",
        }
    }
}

impl fmt::Display for SceneName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for SceneName {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Self, Self::Err> {
        SceneName::ALL
            .into_iter()
            .find(|scene| scene.as_str().eq_ignore_ascii_case(s))
            .ok_or_else(|| {
                format!("unknown scene `{s}`; expected loop, straight, wobbly, highway or aliasing")
            })
    }
}

/// Everything that defines a synthetic sequence. The same config (seed
/// included) always gives byte-identical output.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SyntheticConfig {
    /// The scene and trajectory.
    pub scene: SceneName,
    /// Image width (pixels).
    pub width: usize,
    /// Image height (pixels).
    pub height: usize,
    /// Focal length (pixels, square pixels, principal point at the centre).
    pub focal_length: f64,
    /// Stereo baseline (metres).
    pub baseline: f64,
    /// A stereo calibration error, in pixels every disparity reads short:
    /// the right camera is turned about its y axis by `atan(offset / f)`
    /// while the written calibration says the pair is parallel (real rigs
    /// keep a residual of this kind after rectification). 0: exact.
    #[serde(default)]
    pub disparity_offset: f64,
    /// Frame rate (frames per second).
    pub fps: f64,
    /// Speed along the path (metres per second). For `loop` it is rounded
    /// so that one lap is a whole number of frames.
    pub speed: f64,
    /// Number of frames; `None`: one lap for `loop` (plus the frame back at
    /// the start), 300 for `highway`, 100 m past the second look-alike place
    /// for `aliasing` (300 frames at its default speed), 200 for the others.
    pub frames: Option<usize>,
    /// Seed of the world's textures, the shake and the image noise.
    pub seed: u64,
    /// Standard deviation of the Gaussian pixel noise (gray levels).
    pub pixel_noise: f64,
    /// Relative amplitude of the smooth per-frame exposure change (gain
    /// within `1 ± exposure_variation`), 0 to turn it off.
    pub exposure_variation: f64,
    /// Sub-poses averaged per image for motion blur; 1 turns blur off.
    pub blur_samples: usize,
    /// Fraction of the frame interval the shutter is open (blur length).
    pub shutter: f64,
    /// Rendering threads; 0 uses every core.
    #[serde(default)]
    pub threads: usize,
    /// A hard imaging condition (light change, low light, a kidnap).
    #[serde(default)]
    pub condition: Condition,
}

impl Default for SyntheticConfig {
    fn default() -> Self {
        Self::for_scene(SceneName::Loop)
    }
}

impl SyntheticConfig {
    /// The defaults for a scene: 640×480, f = 400 px (77° horizontal field
    /// of view, close to KITTI's 81°); a car at 10 m/s (25 m/s on the
    /// highway) and 10 fps with a 0.5 m baseline outdoors (`aliasing` is
    /// driven like `straight`), a walker at
    /// 1.2 m/s and 20 fps with a 0.12 m baseline indoors.
    pub fn for_scene(scene: SceneName) -> Self {
        let (baseline, fps, speed) = match scene {
            SceneName::Loop | SceneName::Straight | SceneName::Aliasing => (0.5, 10.0, 10.0),
            SceneName::Highway => (0.5, 10.0, 25.0),
            SceneName::Wobbly => (0.12, 20.0, 1.2),
        };
        Self {
            scene,
            width: 640,
            height: 480,
            focal_length: 400.0,
            baseline,
            disparity_offset: 0.0,
            fps,
            speed,
            frames: None,
            seed: 0,
            pixel_noise: 1.0,
            exposure_variation: 0.05,
            blur_samples: 1,
            shutter: 0.5,
            threads: 0,
            condition: Condition::Normal,
        }
    }

    /// The same config without pixel noise, exposure change or blur
    /// (exact images for geometric checks).
    pub fn noiseless(mut self) -> Self {
        self.pixel_noise = 0.0;
        self.exposure_variation = 0.0;
        self.blur_samples = 1;
        self
    }

    /// Checks every value and says which one is wrong.
    pub fn validate(&self) -> Result<()> {
        let invalid = |field: &'static str, reason: String| {
            Err(SyntheticError::InvalidConfig { field, reason })
        };
        for (field, side) in [("width", self.width), ("height", self.height)] {
            if !(16..=8192).contains(&side) {
                return invalid(field, format!("is {side}; it must lie in 16..=8192 pixels"));
            }
        }
        let positive = [
            ("focal_length", self.focal_length),
            ("baseline", self.baseline),
            ("fps", self.fps),
            ("speed", self.speed),
        ];
        for (field, value) in positive {
            if !(value.is_finite() && value > 0.0) {
                return invalid(field, format!("is {value}; it must be positive"));
            }
        }
        if !(self.disparity_offset.is_finite() && self.disparity_offset.abs() <= 5.0) {
            return invalid(
                "disparity_offset",
                format!("is {}; it must lie in -5..=5 pixels", self.disparity_offset),
            );
        }
        if self.frames == Some(0) {
            return invalid("frames", "is 0; ask for at least one frame".into());
        }
        if !(self.pixel_noise.is_finite() && (0.0..=50.0).contains(&self.pixel_noise)) {
            return invalid(
                "pixel_noise",
                format!(
                    "is {}; it must lie in [0, 50] gray levels",
                    self.pixel_noise
                ),
            );
        }
        if !(0.0..=0.5).contains(&self.exposure_variation) {
            return invalid(
                "exposure_variation",
                format!("is {}; it must lie in [0, 0.5]", self.exposure_variation),
            );
        }
        if !(1..=64).contains(&self.blur_samples) {
            return invalid(
                "blur_samples",
                format!(
                    "is {}; it must lie in 1..=64 (1 = no blur)",
                    self.blur_samples
                ),
            );
        }
        if !(0.0..=1.0).contains(&self.shutter) {
            return invalid(
                "shutter",
                format!("is {}; it must lie in [0, 1]", self.shutter),
            );
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scene_names_round_trip() {
        for scene in SceneName::ALL {
            assert_eq!(scene.to_string().parse::<SceneName>().unwrap(), scene);
        }
        assert_eq!("LOOP".parse::<SceneName>().unwrap(), SceneName::Loop);
        assert_eq!("highway".parse::<SceneName>().unwrap(), SceneName::Highway);
        assert_eq!(
            "aliasing".parse::<SceneName>().unwrap(),
            SceneName::Aliasing
        );
        assert_eq!(SceneName::Aliasing.to_string(), "aliasing");
        assert_eq!(
            "Aliasing".parse::<SceneName>().unwrap().as_str(),
            "aliasing"
        );
        assert!("ring"
            .parse::<SceneName>()
            .unwrap_err()
            .contains("loop, straight"));
    }

    #[test]
    fn defaults_are_valid_and_bad_values_are_named() {
        for scene in SceneName::ALL {
            SyntheticConfig::for_scene(scene).validate().unwrap();
        }
        let c = SyntheticConfig {
            baseline: -1.0,
            ..SyntheticConfig::default()
        };
        let e = c.validate().unwrap_err().to_string();
        assert!(e.contains("baseline"), "{e}");
        let c = SyntheticConfig {
            frames: Some(0),
            ..SyntheticConfig::default()
        };
        assert!(c.validate().unwrap_err().to_string().contains("frames"));
    }

    #[test]
    fn config_round_trips_through_json() {
        let c = SyntheticConfig::for_scene(SceneName::Wobbly);
        let json = serde_json::to_string(&c).unwrap();
        assert_eq!(serde_json::from_str::<SyntheticConfig>(&json).unwrap(), c);
    }
}
