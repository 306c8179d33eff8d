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
}
