//! The scale drift of a monocular trajectory: how the estimate's scale
//! changes along the path. The scale of a stretch is the ground truth's
//! path length over the estimate's (a straight stretch has one too, where a
//! Sim(3) fit is degenerate); the drift is the last third's scale over the
//! first third's (1: none).

use super::trajectory::Trajectory;

/// The scale of the first and last thirds of a trajectory, and their ratio.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ScaleDrift {
    /// Ground-truth path length over the estimate's, first third.
    pub first_third: f64,
    /// The same for the last third.
    pub last_third: f64,
    /// `last_third / first_third`.
    pub ratio: f64,
}

fn path_length(t: &Trajectory, range: std::ops::Range<usize>) -> f64 {
    t.poses[range]
        .windows(2)
        .map(|w| (w[1].translation.vector - w[0].translation.vector).norm())
        .sum()
}

/// The scale drift of `estimate` against `reference` (poses paired one to
/// one); `None` below 6 poses or when a third of either has no length.
pub fn scale_drift(reference: &Trajectory, estimate: &Trajectory) -> Option<ScaleDrift> {
    let n = reference.len().min(estimate.len());
    if n < 6 {
        return None;
    }
    let third = n / 3;
    let scale = |range: std::ops::Range<usize>| -> Option<f64> {
        let e = path_length(estimate, range.clone());
        let r = path_length(reference, range);
        (e > 0.0 && r > 0.0 && e.is_finite() && r.is_finite()).then_some(r / e)
    };
    let first_third = scale(0..third + 1)?;
    let last_third = scale(n - third - 1..n)?;
    Some(ScaleDrift {
        first_third,
        last_third,
        ratio: last_third / first_third,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Translation3, UnitQuaternion};

    fn line(steps: &[f64]) -> Trajectory {
        let mut x = 0.0;
        let mut poses = vec![Isometry3::identity()];
        for s in steps {
            x += s;
            poses.push(Isometry3::from_parts(
                Translation3::new(x, 0.0, 0.0),
                UnitQuaternion::identity(),
            ));
        }
        Trajectory::new((0..poses.len()).map(|i| i as f64).collect(), poses)
    }

    #[test]
    fn a_shrinking_estimate_has_a_known_drift() {
        let truth = line(&[1.0; 8]);
        // The estimate's steps shrink from 0.5 to 0.25 (scale 2 → 4).
        let estimate = line(&[0.5, 0.5, 0.5, 0.4, 0.3, 0.25, 0.25, 0.25]);
        let d = scale_drift(&truth, &estimate).unwrap_or_else(|| panic!("no drift"));
        assert!((d.first_third - 2.0).abs() < 1e-12, "{d:?}");
        assert!((d.last_third - 4.0).abs() < 1e-12, "{d:?}");
        assert!((d.ratio - 2.0).abs() < 1e-12);
        assert_eq!(scale_drift(&truth, &line(&[0.0; 8])), None);
        assert_eq!(scale_drift(&line(&[1.0; 3]), &line(&[1.0; 3])), None);
    }
}
