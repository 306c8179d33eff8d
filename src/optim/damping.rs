//! Levenberg–Marquardt damping with Nielsen's update, shared by the solvers.
//!
//! The solvers minimise `F(x) = Σ ρ(χ²ᵢ)` by solving `(H + μI) δ = −b` with
//! the Gauss–Newton (IRLS) Hessian `H = Σ JᵀwΩJ` and gradient `b = Σ JᵀwΩr`.
//! The quadratic model predicts the decrease `δᵀ(μδ − b)`; the gain ratio
//! `ρ = actual / predicted` accepts a step when positive.

/// Nielsen's damping state: `μ` and its growth factor `ν`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NielsenDamping {
    mu: f64,
    nu: f64,
}

impl NielsenDamping {
    /// g2o's default `τ` for the initial damping `μ₀ = τ · max diag(H)`.
    pub const DEFAULT_TAU: f64 = 1e-5;

    /// Starts with `μ = τ · max_diagonal` (at least `τ · 1e-9`, so the system stays regular).
    pub fn new(max_diagonal: f64, tau: f64) -> Self {
        Self {
            mu: tau * max_diagonal.max(1e-9),
            nu: 2.0,
        }
    }

    /// The current damping `μ`.
    pub fn mu(&self) -> f64 {
        self.mu
    }

    /// After an accepted step with gain ratio `rho > 0`:
    /// `μ ← μ · max(1/3, 1 − (2ρ − 1)³)`, `ν ← 2`.
    pub fn accept(&mut self, rho: f64) {
        let factor = 1.0 - (2.0 * rho - 1.0).powi(3);
        self.mu *= factor.max(1.0 / 3.0);
        self.nu = 2.0;
    }

    /// After a rejected step: `μ ← μ · ν`, `ν ← 2ν`.
    pub fn reject(&mut self) {
        self.mu *= self.nu;
        self.nu *= 2.0;
    }
}

/// The decrease the damped quadratic model predicts for step `δ`:
/// `μ|δ|² − δᵀb`, from `|δ|²` and `δᵀb`.
pub fn predicted_decrease(mu: f64, step_norm_squared: f64, step_dot_gradient: f64) -> f64 {
    mu * step_norm_squared - step_dot_gradient
}

/// The gain ratio `ρ = actual / predicted`; `−∞` when the new cost is not
/// finite or the prediction is not positive, so such steps are rejected.
pub fn gain_ratio(old_cost: f64, new_cost: f64, predicted: f64) -> f64 {
    if !new_cost.is_finite() || predicted <= 0.0 || predicted.is_nan() {
        return f64::NEG_INFINITY;
    }
    (old_cost - new_cost) / predicted
}
