//! Small dense solves behind the two-view geometry: null vectors of the DLT /
//! 8-point systems, 3×3 and 4×4 SVDs. Every routine checks its input is finite
//! and bounds the SVD iterations, so it returns `None` instead of panicking or
//! looping on degenerate input.

use nalgebra::{DMatrix, Matrix3, Matrix4, Rotation3, SVector, UnitQuaternion, Vector3, Vector4};

/// Iteration cap handed to nalgebra's SVD (it loops forever with 0).
const MAX_SVD_ITERATIONS: usize = 10_000;

fn svd_eps() -> f64 {
    f64::EPSILON * 5.0
}

/// Rows above which [`null_vector9`] solves `AᵀA` (9×9) instead of `A`.
const DIRECT_ROWS_MAX: usize = 32;

/// The unit vector `x` minimising `‖A·x‖` for the rows of `A` (the right singular
/// vector of the smallest singular value). Fewer than 9 rows are padded with
/// zero rows so the SVD is full; more than [`DIRECT_ROWS_MAX`] rows go through
/// the 9×9 normal matrix `AᵀA`, which has the same right singular vectors.
pub(crate) fn null_vector9(rows: &[[f64; 9]]) -> Option<SVector<f64, 9>> {
    if rows.is_empty() || rows.iter().flatten().any(|v| !v.is_finite()) {
        return None;
    }
    let m = if rows.len() > DIRECT_ROWS_MAX {
        let mut ata = DMatrix::<f64>::zeros(9, 9);
        for r in rows {
            for i in 0..9 {
                for j in i..9 {
                    ata[(i, j)] += r[i] * r[j];
                }
            }
        }
        for i in 0..9 {
            for j in 0..i {
                ata[(i, j)] = ata[(j, i)];
            }
        }
        ata
    } else {
        let mut a = DMatrix::<f64>::zeros(rows.len().max(9), 9);
        for (i, r) in rows.iter().enumerate() {
            for (j, v) in r.iter().enumerate() {
                a[(i, j)] = *v;
            }
        }
        a
    };
    if !m.iter().all(|v| v.is_finite()) {
        return None;
    }
    let svd = nalgebra::SVD::try_new(m, false, true, svd_eps(), MAX_SVD_ITERATIONS)?;
    let v_t = svd.v_t?;
    if v_t.nrows() < 9 {
        return None;
    }
    let x = SVector::<f64, 9>::from_iterator(v_t.row(8).iter().copied());
    let norm = x.norm();
    (norm.is_finite() && norm > 0.0).then(|| x / norm)
}

/// A 9-vector read row-major into a 3×3 matrix (Eigen's `RowMajor` map in ORB-SLAM3).
pub(crate) fn matrix_from_row_major(x: &SVector<f64, 9>) -> Matrix3<f64> {
    Matrix3::new(x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7], x[8])
}

/// SVD `M = U·diag(s)·Vᵀ` of a 3×3 matrix, singular values in descending
/// order, non-negative. Goes through nalgebra's general (dynamic) SVD rather
/// than its special 3×3 path, so `U` and `V` stay consistent with `M`.
pub(crate) fn svd3(m: &Matrix3<f64>) -> Option<(Matrix3<f64>, Vector3<f64>, Matrix3<f64>)> {
    if !m.iter().all(|v| v.is_finite()) {
        return None;
    }
    let d = DMatrix::from_iterator(3, 3, m.iter().copied());
    let svd = nalgebra::SVD::try_new(d, true, true, svd_eps(), MAX_SVD_ITERATIONS)?;
    let (u, v_t) = (svd.u?, svd.v_t?);
    if u.shape() != (3, 3) || v_t.shape() != (3, 3) || svd.singular_values.len() != 3 {
        return None;
    }
    let u = Matrix3::from_iterator(u.iter().copied());
    let v = Matrix3::from_iterator(v_t.iter().copied()).transpose();
    let s = Vector3::from_iterator(svd.singular_values.iter().copied());
    Some((u, s, v))
}

/// The unit right singular vector of a 4×4 matrix's smallest singular value.
pub(crate) fn null_vector4(m: &Matrix4<f64>) -> Option<Vector4<f64>> {
    if !m.iter().all(|v| v.is_finite()) {
        return None;
    }
    let svd = nalgebra::SVD::try_new(*m, false, true, svd_eps(), MAX_SVD_ITERATIONS)?;
    let v_t = svd.v_t?;
    Some(v_t.row(3).transpose())
}

/// The rotation nearest to `r` (orthonormalised through its SVD, determinant
/// forced to +1), as a unit quaternion. `None` when `r` is not finite.
pub(crate) fn nearest_rotation(r: &Matrix3<f64>) -> Option<UnitQuaternion<f64>> {
    let (u, _, v) = svd3(r)?;
    let mut q = u * v.transpose();
    if q.determinant() < 0.0 {
        let mut u2 = u;
        u2.column_mut(2).neg_mut();
        q = u2 * v.transpose();
    }
    Some(UnitQuaternion::from_rotation_matrix(
        &Rotation3::from_matrix_unchecked(q),
    ))
}
