//! Robust kernels applied to an edge's squared error `s = eᵀ Ω e`.

/// A robust kernel `ρ(s)` on the squared error `s = eᵀ Ω e` of one edge.
///
/// The solver uses iteratively reweighted least squares: the edge's
/// contribution to the normal equations is scaled by `ρ'(s)` and its
/// contribution to χ² is `ρ(s)` (g2o's approximation, second-order term of
/// `ρ` dropped).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RobustKernel {
    /// Huber: `ρ(s) = s` for `s ≤ δ²`, else `2δ√s − δ²`, with `width = δ`
    /// in units of the whitened error (`√s`).
    Huber {
        /// The threshold `δ` on `√s` beyond which the cost grows linearly.
        width: f64,
    },
}

impl RobustKernel {
    /// The kernel's width parameter.
    pub fn width(&self) -> f64 {
        match self {
            Self::Huber { width } => *width,
        }
    }

    /// `ρ(s)`: the edge's contribution to χ².
    pub fn cost(&self, squared_error: f64) -> f64 {
        match self {
            Self::Huber { width } => {
                let threshold = width * width;
                if squared_error <= threshold {
                    squared_error
                } else {
                    2.0 * width * squared_error.sqrt() - threshold
                }
            }
        }
    }

    /// `ρ'(s)`: the weight of the edge in the normal equations.
    pub fn weight(&self, squared_error: f64) -> f64 {
        match self {
            Self::Huber { width } => {
                if squared_error <= width * width {
                    1.0
                } else {
                    width / squared_error.sqrt()
                }
            }
        }
    }
}

/// `(ρ(s), ρ'(s))` for an optional kernel; no kernel means `(s, 1)`.
pub(super) fn robust_cost_and_weight(
    kernel: Option<&RobustKernel>,
    squared_error: f64,
) -> (f64, f64) {
    match kernel {
        None => (squared_error, 1.0),
        Some(kernel) => (kernel.cost(squared_error), kernel.weight(squared_error)),
    }
}
