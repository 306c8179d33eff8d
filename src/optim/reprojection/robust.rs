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
