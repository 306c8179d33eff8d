//! Pose polishing (not in ORB-SLAM3, which leaves it to the bundle adjustment
//! that follows initialisation): Levenberg–Marquardt on the Sampson epipolar
//! error, in pixels, of the points the accepted hypothesis triangulated.
//! Five degrees of freedom: a rotation increment and a translation direction
//! on the unit sphere.

use nalgebra::{Matrix3, Matrix5, Point2, Rotation3, Vector3, Vector5};

use super::homography::k_inverse;
use super::triangulate::check_rt;
use super::{PinholeIntrinsics, Solution, TwoViewParams};

/// Levenberg–Marquardt iterations at most.
const MAX_ITERATIONS: usize = 30;

/// Central-difference step for the numeric Jacobian.
const STEP: f64 = 1e-7;

/// Stop when the relative cost decrease falls below this.
const MIN_RELATIVE_DECREASE: f64 = 1e-10;

/// The skew-symmetric matrix `[v]×`.
fn hat(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// Two unit vectors completing `t` (unit) to an orthonormal basis.
fn tangent_basis(t: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let helper = if t.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let b1 = t.cross(&helper).normalize();
    let b2 = t.cross(&b1);
    (b1, b2)
}

struct Problem<'a> {
    k_inv: Matrix3<f64>,
    pixels1: Vec<&'a Point2<f64>>,
    pixels2: Vec<&'a Point2<f64>>,
}

impl Problem<'_> {
    /// `(R, t)` moved by `δ = [ω, β]`: `R ← exp(ω)·R`, `t ← normalise(t + β₁b₁ + β₂b₂)`.
    fn apply(r: &Matrix3<f64>, t: &Vector3<f64>, d: &Vector5<f64>) -> (Matrix3<f64>, Vector3<f64>) {
        let (b1, b2) = tangent_basis(t);
        let rot = Rotation3::new(Vector3::new(d[0], d[1], d[2])).into_inner() * r;
        let t = (t + b1 * d[3] + b2 * d[4]).normalize();
        (rot, t)
    }

    /// Sampson errors (pixels) of every point under `(R, t)`.
    fn residuals(&self, r: &Matrix3<f64>, t: &Vector3<f64>, out: &mut Vec<f64>) {
        let f = self.k_inv.transpose() * hat(t) * r * self.k_inv;
        let ft = f.transpose();
        out.clear();
        for (p1, p2) in self.pixels1.iter().zip(&self.pixels2) {
            let x1 = Vector3::new(p1.x, p1.y, 1.0);
            let x2 = Vector3::new(p2.x, p2.y, 1.0);
            let l2 = f * x1;
            let l1 = ft * x2;
            let den = (l2.x * l2.x + l2.y * l2.y + l1.x * l1.x + l1.y * l1.y).sqrt();
            out.push(if den > 0.0 { x2.dot(&l2) / den } else { 0.0 });
        }
    }
}

/// Polishes `T_21 = [R | t]` (`t` unit) on the matches flagged in `use_match`.
/// Returns the refined pose, or `None` when there are too few points, the
/// input is not finite, or no step lowered the cost.
pub(crate) fn refine_pose(
    camera: &PinholeIntrinsics,
    r: &Matrix3<f64>,
    t: &Vector3<f64>,
    pixels1: &[Point2<f64>],
    pixels2: &[Point2<f64>],
    use_match: &[bool],
) -> Option<(Matrix3<f64>, Vector3<f64>)> {
    let chosen: Vec<usize> = use_match
        .iter()
        .enumerate()
        .filter(|(_, &b)| b)
        .map(|(i, _)| i)
        .collect();
    let finite = r.iter().chain(t.iter()).all(|v| v.is_finite());
    let nonzero = t.norm() > 0.0;
    if chosen.len() < 8 || !finite || !nonzero {
        return None;
    }
    let problem = Problem {
        k_inv: k_inverse(camera),
        pixels1: chosen.iter().filter_map(|&i| pixels1.get(i)).collect(),
        pixels2: chosen.iter().filter_map(|&i| pixels2.get(i)).collect(),
    };
    let (mut r, mut t) = (*r, t.normalize());
    let mut res = Vec::with_capacity(chosen.len());
    problem.residuals(&r, &t, &mut res);
    let mut cost: f64 = res.iter().map(|e| e * e).sum();
    if !cost.is_finite() {
        return None;
    }
    let initial_cost = cost;
    let mut lambda = 1e-3;
    let (mut plus, mut minus) = (Vec::new(), Vec::new());
    let mut jac = vec![Vector5::<f64>::zeros(); res.len()];
    for _ in 0..MAX_ITERATIONS {
        // Numeric Jacobian by central differences.
        for k in 0..5 {
            let mut d = Vector5::zeros();
            d[k] = STEP;
            let (rp, tp) = Problem::apply(&r, &t, &d);
            let (rm, tm) = Problem::apply(&r, &t, &(-d));
            problem.residuals(&rp, &tp, &mut plus);
            problem.residuals(&rm, &tm, &mut minus);
            for (j, (a, b)) in jac.iter_mut().zip(plus.iter().zip(&minus)) {
                j[k] = (a - b) / (2.0 * STEP);
            }
        }
        let mut jtj = Matrix5::zeros();
        let mut jtr = Vector5::zeros();
        for (j, e) in jac.iter().zip(&res) {
            jtj += j * j.transpose();
            jtr += j * *e;
        }
        if !jtj.iter().chain(jtr.iter()).all(|v| v.is_finite()) {
            break;
        }
        let mut improved = false;
        for _ in 0..10 {
            let mut a = jtj;
            for i in 0..5 {
                a[(i, i)] += lambda * jtj[(i, i)].max(1e-12);
            }
            let Some(delta) = a.cholesky().map(|c| c.solve(&(-jtr))) else {
                lambda *= 10.0;
                continue;
            };
            let (rn, tn) = Problem::apply(&r, &t, &delta);
            problem.residuals(&rn, &tn, &mut plus);
            let new_cost: f64 = plus.iter().map(|e| e * e).sum();
            if new_cost.is_finite() && new_cost < cost {
                let decrease = (cost - new_cost) / cost.max(f64::MIN_POSITIVE);
                (r, t, cost) = (rn, tn, new_cost);
                std::mem::swap(&mut res, &mut plus);
                lambda = (lambda * 0.1).max(1e-12);
                improved = decrease > MIN_RELATIVE_DECREASE;
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    (cost < initial_cost && r.iter().chain(t.iter()).all(|v| v.is_finite())).then_some((r, t))
}

/// Refines the accepted pose on the Sampson error of its triangulated points
/// (not in ORB-SLAM3) and re-triangulates the chosen model's
/// inliers (those `CheckRT` saw) under it; the refined solution replaces the
/// accepted one only when it keeps at least as many good points.
pub(crate) fn polish(
    camera: &PinholeIntrinsics,
    solution: Solution,
    pixels1: &[Point2<f64>],
    pixels2: &[Point2<f64>],
    params: &TwoViewParams,
) -> Solution {
    let used: Vec<bool> = solution.check.points.iter().map(Option::is_some).collect();
    let Some((rotation, translation)) = refine_pose(
        camera,
        &solution.rotation,
        &solution.translation,
        pixels1,
        pixels2,
        &used,
    ) else {
        return solution;
    };
    let check = check_rt(
        camera,
        &rotation,
        &translation,
        pixels1,
        pixels2,
        &solution.inliers,
        4.0 * params.sigma * params.sigma,
    );
    if check.n_good >= solution.check.n_good {
        Solution {
            rotation,
            translation,
            check,
            inliers: solution.inliers,
        }
    } else {
        solution
    }
}
