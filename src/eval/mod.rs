//! Trajectory evaluation: KITTI / TUM / EuRoC file I/O, timestamp association,
//! the KITTI odometry metric (devkit semantics), ATE and RPE (evo semantics),
//! and plots. Independent of the SLAM core.

pub mod ate;
pub mod bar_plot;
pub mod error;
pub mod format;
pub mod io;
pub mod kitti_metric;
pub mod line_plot;
pub mod place_recognition;
pub mod plot;
pub mod report;
pub mod rpe;
pub mod scale_drift;
pub mod stats;
pub mod sync;
pub mod table;
pub mod trajectory;
pub mod umeyama;

pub use ate::{align, ate, Alignment, AteResult};
pub use bar_plot::{write_grouped_bar_plot, BarSeries};
pub use error::{EvalError, Result};
pub use format::TrajectoryFormat;
pub use io::{
    read_euroc, read_kitti, read_kitti_with_times, read_trajectory, read_tum,
    trajectory_from_matrices, write_euroc, write_kitti, write_trajectory, write_tum,
};
pub use kitti_metric::{kitti_metric, KittiMetric, LengthError, SegmentError};
pub use line_plot::{write_line_panels, LinePanel, LineSeries};
pub use plot::{
    write_error_plot, write_trajectory_plot, write_trajectory_plot_with_links, PlotPlane,
};
pub use report::{
    evaluate, pair_trajectories, AteReport, EvalOptions, EvalReport, Pairing, RpeReport,
};
pub use rpe::{rpe, RpeDelta, RpeOptions, RpeResult};
pub use scale_drift::{scale_drift, ScaleDrift};
pub use stats::ErrorStats;
pub use sync::{associate, associate_with, AssociatedPair, DEFAULT_MAX_DIFF};
pub use trajectory::Trajectory;
pub use umeyama::{umeyama, Similarity};
