//! Errors of the optimisation back end. Each module adds its variants in
//! its own marked section of [`OptimError`].

use thiserror::Error;

/// Why an optimisation problem was refused or could not be solved.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum OptimError {
    // ---- Pose-graph optimisation (src/optim/pose_graph/) ----
    /// An edge names a node that does not exist.
    #[error("edge {edge} refers to node {node}, but the graph has {nodes} nodes")]
    NodeOutOfRange {
        /// Index the edge would have had.
        edge: usize,
        /// The offending node index.
        node: usize,
        /// Number of nodes in the graph.
        nodes: usize,
    },
    /// A node index passed to a graph accessor does not exist.
    #[error("node {node} does not exist; the graph has {nodes} nodes")]
    UnknownNode {
        /// The offending node index.
        node: usize,
        /// Number of nodes in the graph.
        nodes: usize,
    },
    /// An edge connects a node to itself.
    #[error("edge {edge} connects node {node} to itself")]
    SelfLoopEdge {
        /// Index the edge would have had.
        edge: usize,
        /// The node at both ends.
        node: usize,
    },
    /// An edge's measurement has a NaN or infinite entry (or a non-positive scale).
    #[error("edge {edge} has a non-finite or invalid measurement")]
    InvalidMeasurement {
        /// Index the edge would have had.
        edge: usize,
    },
    /// A node's pose has a NaN or infinite entry (or a non-positive scale).
    #[error("node {node} has a non-finite or invalid pose")]
    InvalidNode {
        /// The offending node index.
        node: usize,
    },
    /// An edge's information matrix is not symmetric positive definite (or not finite).
    #[error("edge {edge}: information matrix is not symmetric positive definite")]
    InformationNotPositiveDefinite {
        /// Index the edge would have had.
        edge: usize,
    },
    /// A robust-kernel parameter is not a finite positive number.
    #[error("edge {edge}: robust kernel width {width} is not finite and positive")]
    InvalidKernelWidth {
        /// Index the edge would have had.
        edge: usize,
        /// The offending width.
        width: f64,
    },
    /// A solver option is out of its valid range.
    #[error("solver option {option} = {value} is invalid")]
    InvalidOption {
        /// Name of the option.
        option: &'static str,
        /// The offending value.
        value: f64,
    },
    /// The sparse symbolic analysis failed (allocation or index overflow).
    #[error("sparse symbolic factorisation failed: {reason}")]
    SymbolicFactorisation {
        /// faer's description of the failure.
        reason: String,
    },
    /// The normal equations were not positive definite in a Gauss–Newton step
    /// (a part of the graph has no fixed node, or the information is degenerate).
    #[error("normal equations not positive definite at iteration {iteration} (pivot {pivot})")]
    NotPositiveDefinite {
        /// The iteration (0-based) whose step failed.
        iteration: usize,
        /// The scalar column at which the Cholesky pivot was not positive.
        pivot: usize,
    },

    // ---- Pose-only optimisation and local bundle adjustment
    // ---- (src/optim/pose_only/, src/optim/local_ba/) ----
    /// Fewer correspondences than the solver needs to constrain the unknowns.
    #[error("too few correspondences: {actual} given, at least {required} required")]
    InsufficientCorrespondences {
        /// The minimum the solver accepts.
        required: usize,
        /// How many were given.
        actual: usize,
    },
    /// The bundle-adjustment problem has no observations at all.
    #[error("the problem has no observations")]
    NoObservations,
    /// A bundle-adjustment observation refers to a pose that does not exist.
    #[error("observation {observation} refers to pose {pose}, but there are only {poses} poses")]
    PoseIndexOutOfRange {
        /// Index of the observation.
        observation: usize,
        /// The pose index it gives.
        pose: usize,
        /// How many poses the problem has.
        poses: usize,
    },
    /// A bundle-adjustment observation refers to a point that does not exist.
    #[error(
        "observation {observation} refers to point {point}, but there are only {points} points"
    )]
    PointIndexOutOfRange {
        /// Index of the observation.
        observation: usize,
        /// The point index it gives.
        point: usize,
        /// How many points the problem has.
        points: usize,
    },
    /// The per-pose `fixed` flags do not match the number of poses.
    #[error("{flags} fixed flags given for {poses} poses")]
    FixedFlagsLength {
        /// Number of flags.
        flags: usize,
        /// Number of poses.
        poses: usize,
    },
    /// An input value is NaN or infinite (or an information weight is not
    /// positive, or a camera focal length not positive).
    #[error("{what} {index} is not finite or out of its valid range")]
    InvalidValue {
        /// What kind of input: "camera", "pose", "point" or "observation".
        what: &'static str,
        /// Its index (0 for the camera).
        index: usize,
    },
    /// The cost at the initial estimate is not finite (a point at zero depth).
    #[error("the cost at the initial estimate is not finite (a point at zero depth?)")]
    NonFiniteInitialCost,
}
