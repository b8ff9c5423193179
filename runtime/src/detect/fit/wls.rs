//! Weighted least squares and the scores built on it: the whitened design solved by SVD
//! (never the normal equations), the weighted mean, and AICc.

use nalgebra::{DMatrix, DVector};

/// A weighted least-squares solution: coefficients, their covariance, χ² and the
/// condition number of the whitened design.
pub(crate) struct LsFit {
    pub beta: Vec<f64>,
    pub cov: DMatrix<f64>,
    pub chi2: f64,
    pub cond: f64,
}

/// Singular values below this fraction of the largest make a design rank-deficient.
const RANK_TOL: f64 = 1e-10;

/// Weighted LS of `a β ≈ y` with row standard errors `se`; `None` when rank-deficient.
pub(crate) fn weighted_ls(a: &DMatrix<f64>, y: &[f64], se: &[f64]) -> Option<LsFit> {
    let (n, m) = a.shape();
    // Fewer points than coefficients: the fit is underdetermined (and a thin SVD has only
    // `n` singular values). Rows must match the errors given.
    if n < m || m == 0 || y.len() != n || se.len() != n {
        return None;
    }
    // shape: checked just above: `n ≥ m ≥ 1` rows of `a`, `y` and `se`, so the thin SVD has
    // `m` singular values, `u` is `n × m` and `v_t` is `m × m`.
    let mut aw = a.clone();
    let mut yw = DVector::zeros(n);
    for i in 0..n {
        for j in 0..m {
            aw[(i, j)] /= se[i];
        }
        yw[i] = y[i] / se[i];
    }
    // Column scaling makes the rank test and the condition number independent of units.
    let scale: Vec<f64> = (0..m)
        .map(|j| {
            let c = aw.column(j).norm();
            if c > 0.0 {
                c
            } else {
                1.0
            }
        })
        .collect();
    for (j, &s) in scale.iter().enumerate() {
        aw.column_mut(j).scale_mut(1.0 / s);
    }
    let svd = aw.clone().svd(true, true);
    let smax = svd.singular_values.max();
    let smin = svd.singular_values.min();
    if smax.is_nan() || smax <= 0.0 || smin < RANK_TOL * smax {
        return None;
    }
    let u = svd.u.as_ref()?;
    let vt = svd.v_t.as_ref()?;
    let uty = u.transpose() * &yw;
    let mut z = DVector::zeros(m);
    for k in 0..m {
        z[k] = uty[k] / svd.singular_values[k];
    }
    let bs = vt.transpose() * z;
    let r = &yw - &aw * &bs;
    let mut vs = vt.transpose();
    for k in 0..m {
        vs.column_mut(k).scale_mut(1.0 / svd.singular_values[k]);
    }
    let mut cov = &vs * vs.transpose();
    let mut beta = vec![0.0; m];
    for j in 0..m {
        beta[j] = bs[j] / scale[j];
        for k in 0..m {
            cov[(j, k)] /= scale[j] * scale[k];
        }
    }
    Some(LsFit {
        beta,
        cov,
        chi2: r.norm_squared(),
        cond: smax / smin,
    })
}

/// The inverse-variance weighted mean of `y` (row errors `se`) and its standard error.
pub(crate) fn weighted_mean(y: &[f64], se: &[f64]) -> (f64, f64) {
    let sw: f64 = se.iter().map(|s| 1.0 / (s * s)).sum();
    let m = y.iter().zip(se).map(|(y, s)| y / (s * s)).sum::<f64>() / sw;
    (m, 1.0 / sw.sqrt())
}

/// AICc for a fit with known row variances; `∞` when the sample is too small for the
/// correction (N ≤ K + 1): such a fit is saturated and carries no evidence.
pub(crate) fn aicc(chi2: f64, k: usize, n: usize) -> f64 {
    if n <= k + 1 {
        return f64::INFINITY;
    }
    let (k, n) = (k as f64, n as f64);
    chi2 + 2.0 * k + 2.0 * k * (k + 1.0) / (n - k - 1.0)
}
