//! Least squares by SVD of the row-weighted, column-scaled matrix (never the normal
//! equations), with the singular values kept for conditioning and rank diagnostics.

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatMut, Par};

/// Solution of `min ‖A x − b‖` for a dense row-major `A` (`rows × cols`).
#[derive(Clone, Debug)]
pub(crate) struct LsSolution {
    pub x: Vec<f64>,
    /// Singular values of the column-scaled matrix, descending.
    pub sv: Vec<f64>,
    /// Right singular vector of the smallest singular value (in scaled coordinates).
    pub v_min: Vec<f64>,
    /// Euclidean norms of the columns of `A` before scaling.
    pub col_norms: Vec<f64>,
    /// The pseudo-inverse `A⁺` (row-major `cols × rows`, same truncation as `x`), so that
    /// `x = A⁺ b` and a perturbation `δb` of the right-hand side moves `x` by `A⁺ δb`.
    pub pinv: Vec<f64>,
}

impl LsSolution {
    /// The solution of a problem without columns.
    pub fn empty() -> Self {
        LsSolution {
            x: vec![],
            sv: vec![],
            v_min: vec![],
            col_norms: vec![],
            pinv: vec![],
        }
    }

    /// `σ_max / σ_min` of the column-scaled matrix.
    pub fn condition(&self) -> f64 {
        match (self.sv.first(), self.sv.last()) {
            (Some(&a), Some(&b)) if b > 0.0 => a / b,
            (Some(_), Some(_)) => f64::INFINITY,
            _ => 1.0,
        }
    }
}

/// Solve with unit-norm column scaling. Singular values below `rcond · σ_max` are treated as
/// zero (the caller flags those directions as unidentifiable before trusting `x`). Fails,
/// saying why, on non-finite entries or when the SVD does not converge.
pub(crate) fn lstsq(
    a: &[f64],
    b: &[f64],
    rows: usize,
    cols: usize,
    rcond: f64,
) -> Result<LsSolution, String> {
    if a.len() != rows * cols || b.len() != rows || (rows == 0 && cols > 0) {
        return Err(format!(
            "the least-squares problem has {} entries and {} right-hand sides for {rows} rows \
             of {cols} columns",
            a.len(),
            b.len()
        ));
    }
    // shape: checked above: `a` is `rows × cols`, `b` has `rows` entries, and a problem
    // with columns has rows, so the thin SVD has `k = min(rows, cols) ≥ 1` directions,
    // `u` is `rows × k` and `v` is `cols × k`.
    if !a.iter().chain(b).all(|v| v.is_finite()) {
        return Err("the least-squares problem has entries that are not finite".into());
    }
    let mut col_norms = vec![0.0; cols];
    for i in 0..rows {
        for j in 0..cols {
            col_norms[j] += a[i * cols + j] * a[i * cols + j];
        }
    }
    col_norms.iter_mut().for_each(|v| *v = v.sqrt());
    let scale: Vec<f64> = col_norms
        .iter()
        .map(|&n| if n > 0.0 { 1.0 / n } else { 1.0 })
        .collect();
    if cols == 0 {
        return Ok(LsSolution {
            x: vec![],
            sv: vec![],
            v_min: vec![],
            col_norms,
            pinv: vec![],
        });
    }
    let m = Mat::<f64>::from_fn(rows, cols, |i, j| a[i * cols + j] * scale[j]);
    let svd = m
        .thin_svd()
        .map_err(|e| format!("the singular value decomposition did not converge ({e:?})"))?;
    let (u, s, v) = (svd.U(), svd.S().column_vector(), svd.V());
    let k = s.nrows();
    let sv: Vec<f64> = (0..k).map(|i| s[i]).collect();
    let smax = sv.first().copied().unwrap_or(0.0);
    let mut y = vec![0.0; cols];
    // A⁺ = V' Uᵀ with V'[j, r] = v[j, r] · scale[j] / σ_r over the kept directions.
    let mut vs = Mat::<f64>::zeros(cols, k);
    for r in 0..k {
        if sv[r] <= rcond * smax || sv[r] == 0.0 {
            continue;
        }
        let ur = u.col(r);
        let ub: f64 = (0..rows).map(|i| ur[i] * b[i]).sum();
        let c = ub / sv[r];
        for (j, yj) in y.iter_mut().enumerate() {
            *yj += v[(j, r)] * c;
            vs[(j, r)] = v[(j, r)] * scale[j] / sv[r];
        }
    }
    let mut pinv = vec![0.0; cols * rows];
    matmul(
        MatMut::from_row_major_slice_mut(&mut pinv[..], cols, rows),
        Accum::Replace,
        vs.as_ref(),
        u.transpose(),
        1.0,
        Par::Seq,
    );
    let x = y.iter().zip(&scale).map(|(y, s)| y * s).collect();
    let v_min = (0..cols).map(|j| v[(j, k - 1)]).collect();
    Ok(LsSolution {
        x,
        sv,
        v_min,
        col_norms,
        pinv,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_a_badly_scaled_problem_and_reports_rank_loss() {
        // Columns differ in scale by 1e8; the scaled problem is perfectly conditioned.
        let rows = 5;
        let a: Vec<f64> = (0..rows)
            .flat_map(|i| [1e8 * (i as f64 + 1.0), ((i * i) as f64 - 2.0)])
            .collect();
        let x_true = [2e-8, 3.0];
        let b: Vec<f64> = (0..rows)
            .map(|i| a[2 * i] * x_true[0] + a[2 * i + 1] * x_true[1])
            .collect();
        let s = lstsq(&a, &b, rows, 2, 1e-12).unwrap();
        assert!((s.x[0] / x_true[0] - 1.0).abs() < 1e-12);
        assert!((s.x[1] / x_true[1] - 1.0).abs() < 1e-12);
        assert!(s.condition() < 10.0);
        // Duplicate column: rank 1, the null vector weighs both columns equally.
        let a2: Vec<f64> = (0..rows)
            .flat_map(|i| [i as f64 + 1.0, i as f64 + 1.0])
            .collect();
        let s2 = lstsq(&a2, &b, rows, 2, 1e-12).unwrap();
        assert!(s2.condition() > 1e12);
        assert!((s2.v_min[0].abs() - s2.v_min[1].abs()).abs() < 1e-12);
    }
}
