//! Umeyama's least-squares similarity between point sets (evo's `umeyama_alignment`).

use nalgebra::{Isometry3, Matrix3, Point3, Translation3, UnitQuaternion, Vector3};

use super::error::{EvalError, Result};

/// `y ≈ scale · rotation · x + translation`, as a rigid part and a scale.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Similarity {
    /// Rotation and translation.
    pub transform: Isometry3<f64>,
    /// Scale factor (1 when scale is not estimated).
    pub scale: f64,
}

impl Similarity {
    /// Applies the similarity to a point.
    pub fn apply(&self, p: &Point3<f64>) -> Point3<f64> {
        self.transform.rotation * (p * self.scale) + self.transform.translation.vector
    }
}

/// The similarity that maps `source` onto `target` in the least-squares sense
/// (Umeyama 1991); with `with_scale` false the scale is fixed to 1 (SE3).
/// Fails when the points span fewer than two directions.
pub fn umeyama(
    source: &[Point3<f64>],
    target: &[Point3<f64>],
    with_scale: bool,
) -> Result<Similarity> {
    let n = source.len().min(target.len());
    let degenerate = EvalError::DegenerateAlignment { points: n };
    if n == 0 || source.len() != target.len() {
        return Err(degenerate);
    }
    let nf = n as f64;
    let mean_x: Vector3<f64> = source.iter().map(|p| p.coords).sum::<Vector3<f64>>() / nf;
    let mean_y: Vector3<f64> = target.iter().map(|p| p.coords).sum::<Vector3<f64>>() / nf;
    let sigma_x = source
        .iter()
        .map(|p| (p.coords - mean_x).norm_squared())
        .sum::<f64>()
        / nf;
    let mut cov = Matrix3::zeros();
    for (x, y) in source.iter().zip(target) {
        cov += (y.coords - mean_y) * (x.coords - mean_x).transpose();
    }
    cov /= nf;
    let svd = cov.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Err(degenerate);
    };
    let d = svd.singular_values;
    if d.iter().filter(|&&s| s > f64::EPSILON).count() < 2 {
        return Err(degenerate);
    }
    let mut s = Vector3::new(1.0, 1.0, 1.0);
    if u.determinant() * v_t.determinant() < 0.0 {
        // nalgebra sorts singular values in descending order, like numpy.
        s[2] = -1.0;
    }
    let r = u * Matrix3::from_diagonal(&s) * v_t;
    let scale = if with_scale { d.dot(&s) / sigma_x } else { 1.0 };
    let t = mean_y - scale * (r * mean_x);
    let rotation = UnitQuaternion::from_matrix(&r);
    Ok(Similarity {
        transform: Isometry3::from_parts(Translation3::from(t), rotation),
        scale,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cloud() -> Vec<Point3<f64>> {
        (0..20)
            .map(|i| {
                let f = i as f64;
                Point3::new(f.sin() * 3.0, (0.7 * f).cos() * 2.0 + f * 0.1, 0.3 * f)
            })
            .collect()
    }

    #[test]
    fn recovers_known_similarity() {
        let truth = Similarity {
            transform: Isometry3::new(Vector3::new(1.0, -2.0, 3.0), Vector3::new(0.2, -0.5, 1.1)),
            scale: 2.5,
        };
        let x = cloud();
        let y: Vec<_> = x.iter().map(|p| truth.apply(p)).collect();
        let sim3 = umeyama(&x, &y, true).unwrap();
        assert!((sim3.scale - 2.5).abs() < 1e-10);
        assert!(sim3.transform.rotation.angle_to(&truth.transform.rotation) < 1e-10);
        assert!(
            (sim3.transform.translation.vector - truth.transform.translation.vector).norm() < 1e-9
        );
        let se3 = umeyama(&x, &y, false).unwrap();
        assert_eq!(se3.scale, 1.0);
        assert!(se3.transform.rotation.angle_to(&truth.transform.rotation) < 1e-10);
    }

    #[test]
    fn collinear_points_are_degenerate() {
        let x: Vec<_> = (0..10).map(|i| Point3::new(i as f64, 0.0, 0.0)).collect();
        assert!(matches!(
            umeyama(&x, &x, true),
            Err(EvalError::DegenerateAlignment { points: 10 })
        ));
    }
}
