//! The Huber kernel (g2o's `RobustKernelHuber`) on χ² values, and
//! ORB-SLAM3's χ² thresholds.

/// χ² threshold for 2 degrees of freedom at 95 % (mono outliers).
pub const CHI2_MONO_95: f64 = 5.991;
/// χ² threshold for 3 degrees of freedom at 95 % (stereo outliers).
pub const CHI2_STEREO_95: f64 = 7.815;

/// The Huber cost of a χ² value `s`: `s` inside `δ²`, `2δ√s − δ²` beyond.
pub fn huber_cost(chi2: f64, delta: f64) -> f64 {
    if chi2 <= delta * delta {
        chi2
    } else {
        2.0 * delta * chi2.sqrt() - delta * delta
    }
}

/// The IRLS weight `ρ'(s)` of the Huber kernel: 1 inside `δ²`, `δ/√s` beyond.
pub fn huber_weight(chi2: f64, delta: f64) -> f64 {
    if chi2 <= delta * delta {
        1.0
    } else {
        delta / chi2.sqrt()
    }
}

/// The cost and IRLS weight of a χ² value: Huber with `huber_delta` when
/// given, else the plain χ² (weight 1).
pub fn kernel_cost_and_weight(chi2: f64, huber_delta: Option<f64>) -> (f64, f64) {
    match huber_delta {
        Some(delta) => (huber_cost(chi2, delta), huber_weight(chi2, delta)),
        None => (chi2, 1.0),
    }
}
