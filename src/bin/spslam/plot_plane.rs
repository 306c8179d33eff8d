//! `--plot-plane`: the plane of the trajectory plots, shared by `spslam
//! run` and `spslam eval`.

use spslam::eval::{PlotPlane, Trajectory};

/// The plane of a trajectory plot, as given on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum PlotPlaneChoice {
    /// The plane of the ground truth's two largest extents.
    #[default]
    Auto,
    /// x–y (a world frame with z up: TUM, EuRoC).
    Xy,
    /// x–z (a camera frame, y down: KITTI).
    Xz,
    /// y–z.
    Yz,
}

impl PlotPlaneChoice {
    /// The plane to draw `reference` (the ground truth) in.
    pub fn resolve(self, reference: &Trajectory) -> PlotPlane {
        match self {
            Self::Auto => PlotPlane::of_largest_extent(reference),
            Self::Xy => PlotPlane::Xy,
            Self::Xz => PlotPlane::Xz,
            Self::Yz => PlotPlane::Yz,
        }
    }
}
