//! Levenberg–Marquardt damping with Nielsen's update, shared by the solvers.
//!
//! The solvers minimise `F(x) = Σ ρ(χ²ᵢ)` by solving `(H + μD) δ = −b` with
//! the Gauss–Newton (IRLS) Hessian `H = Σ JᵀwΩJ`, gradient `b = Σ JᵀwΩr` and
//! Marquardt's scaling `D = diag(H)` (each entry clamped to
//! [[`MIN_SCALE`], [`MAX_SCALE`]], as Ceres does), so variables of very
//! different stiffness (a near point, a far point, a rotation) are damped
//! alike. The quadratic model predicts the decrease `δᵀ(μDδ − b)`; the gain
//! ratio `ρ = actual / predicted` accepts a step when positive.

/// Smallest diagonal scale (keeps unobserved variables regular).
pub const MIN_SCALE: f64 = 1e-6;
/// Largest diagonal scale.
pub const MAX_SCALE: f64 = 1e32;

/// Marquardt's scale for a diagonal entry of `H`.
pub fn marquardt_scale(diagonal: f64) -> f64 {
    diagonal.clamp(MIN_SCALE, MAX_SCALE)
}

/// Nielsen's damping state: `μ` and its growth factor `ν`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NielsenDamping {
    mu: f64,
    nu: f64,
}

impl NielsenDamping {
    /// The default initial damping `μ₀` (relative to `diag(H)`; Ceres's
    /// initial trust region of 1e4 is `μ₀ = 1e-4`).
    pub const DEFAULT_INITIAL_MU: f64 = 1e-4;

    /// Starts with damping `initial_mu`.
    pub fn new(initial_mu: f64) -> Self {
        Self {
            mu: initial_mu,
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
/// `μ δᵀDδ − δᵀb`, from `δᵀDδ` and `δᵀb`.
pub fn predicted_decrease(mu: f64, step_scaled_norm_squared: f64, step_dot_gradient: f64) -> f64 {
    mu * step_scaled_norm_squared - step_dot_gradient
}

/// The gain ratio `ρ = actual / predicted`; `−∞` when the new cost is not
/// finite or the prediction is not positive, so such steps are rejected.
pub fn gain_ratio(old_cost: f64, new_cost: f64, predicted: f64) -> f64 {
    if !new_cost.is_finite() || predicted <= 0.0 || predicted.is_nan() {
        return f64::NEG_INFINITY;
    }
    (old_cost - new_cost) / predicted
}
