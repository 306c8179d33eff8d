//! Which camera drives the system (ORB-SLAM3's `System::eSensor`, without
//! the IMU variants).

use std::fmt;
use std::str::FromStr;

/// The sensor kind: what a frame holds besides its (left) image.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Sensor {
    /// One camera: no depth; the map's scale is arbitrary and drifts.
    #[serde(rename = "mono")]
    Monocular,
    /// A rectified stereo pair: depth from matching along rows.
    Stereo,
    /// A colour (gray) image with a registered depth image.
    Rgbd,
}

impl Sensor {
    /// Whether frames carry metric depth (stereo or RGB-D): the map has a
    /// scale, a single frame can initialise, and loops are corrected in SE(3).
    pub fn has_depth(self) -> bool {
        !matches!(self, Self::Monocular)
    }

    /// The name used on the command line and in reports.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Monocular => "mono",
            Self::Stereo => "stereo",
            Self::Rgbd => "rgbd",
        }
    }
}

impl fmt::Display for Sensor {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A sensor name that is not `mono`, `stereo` or `rgbd`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown sensor `{0}` (use mono, stereo or rgbd)")]
pub struct UnknownSensor(pub String);

impl FromStr for Sensor {
    type Err = UnknownSensor;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.to_ascii_lowercase().as_str() {
            "mono" | "monocular" => Ok(Self::Monocular),
            "stereo" => Ok(Self::Stereo),
            "rgbd" | "rgb-d" => Ok(Self::Rgbd),
            _ => Err(UnknownSensor(s.to_string())),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for sensor in [Sensor::Monocular, Sensor::Stereo, Sensor::Rgbd] {
            assert_eq!(sensor.as_str().parse::<Sensor>(), Ok(sensor));
        }
        assert!("lidar".parse::<Sensor>().is_err());
        assert!(!Sensor::Monocular.has_depth());
        assert!(Sensor::Rgbd.has_depth());
    }
}
