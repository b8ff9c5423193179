//! Ordinary least squares with classical and Newey–West standard errors.
//!
//! The columns of `X` are scaled to unit norm (`X = Xₛ S⁻¹`), `Xₛ = Q R` by Householder QR,
//! and `R = U Σ Vᵀ` by SVD; then `θₛ = V Σ⁻¹ Uᵀ Qᵀ y` and `θ = S⁻¹ θₛ`. With residuals
//! `e = y − X θ` and `R⁻ᵀ = U Σ⁻¹ Vᵀ`:
//!
//! ```text
//! classical:    cov θₛ = σ̂² R⁻¹ R⁻ᵀ,        σ̂² = eᵀe / (n − p)
//! Newey–West:   cov θₛ = n/(n − p) · R⁻¹ Ω R⁻ᵀ,  gₖ = R⁻ᵀ xₛ,ₖ eₖ,
//!               Ω = Σₖ gₖ gₖᵀ + Σ_{l=1}^{L} (1 − l/(L+1)) Σₖ (gₖ gₖ₋ₗᵀ + gₖ₋ₗ gₖᵀ)
//! ```
//!
//! (`XᵀX = Rᵀ R` is never formed.) The condition number is that of the scaled matrix,
//! `σ_max / σ_min` of `R`.

use super::{BaselineError, Term};
use nalgebra::{DMatrix, DVector};

/// A fitted baseline.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Fit {
    /// The basis columns, in the order of the estimates.
    pub terms: Vec<Term>,
    pub estimates: Vec<f64>,
    /// Classical standard errors: residual variance times `(XᵀX)⁻¹`; right when the
    /// regression's residuals are uncorrelated from row to row.
    pub stderr_ols: Vec<f64>,
    /// Newey–West (HAC, Bartlett kernel) standard errors with lag [`Fit::hac_lag`] rows.
    pub stderr_hac: Vec<f64>,
    /// Lag of the Newey–West sum, in rows.
    pub hac_lag: usize,
    /// Condition number of the column-scaled regression matrix.
    pub condition: f64,
    /// Rows in the regression.
    pub rows: usize,
    /// RMS of the residuals (force units).
    pub residual_rms: f64,
}

impl Fit {
    /// The estimate and its two standard errors `(θ, se_ols, se_hac)` of `term`.
    pub fn get(&self, term: Term) -> Option<(f64, f64, f64)> {
        let i = self.terms.iter().position(|t| *t == term)?;
        Some((self.estimates[i], self.stderr_ols[i], self.stderr_hac[i]))
    }
}

/// Condition number above which the columns count as collinear.
const MAX_CONDITION: f64 = 1e10;

/// Least squares of `y` on the columns of `x` (`rows × terms.len()`).
pub(super) fn fit(
    terms: &[Term],
    x: DMatrix<f64>,
    y: DVector<f64>,
    hac_lag: usize,
) -> Result<Fit, BaselineError> {
    fit_compensated(terms, x, y, hac_lag, None)
}

/// [`fit`], bias-compensated where `noise` is given: the expected part of `XᵀX` that noise
/// in the columns adds (`p × p`, errors in the variables) is taken out, `θ = (XᵀX − D)⁻¹ Xᵀy`
/// with `XᵀX = RᵀR` from the QR factor (never formed from `X`), and the scores
/// `xₖ eₖ + D θ / n` (zero mean at the truth) enter the sandwich through `(XᵀX − D)⁻¹`.
pub(super) fn fit_compensated(
    terms: &[Term],
    mut x: DMatrix<f64>,
    y: DVector<f64>,
    hac_lag: usize,
    noise: Option<&DMatrix<f64>>,
) -> Result<Fit, BaselineError> {
    let (n, p) = x.shape();
    if n <= p {
        return Err(BaselineError::TooFewRows { rows: n, cols: p });
    }
    let scale: Vec<f64> = x
        .column_iter()
        .map(|c| {
            let s = c.norm();
            if s > 0.0 {
                1.0 / s
            } else {
                1.0
            }
        })
        .collect();
    for (mut c, s) in x.column_iter_mut().zip(&scale) {
        c *= *s;
    }
    let xs = x;
    let qr = xs.clone().qr();
    let mut qty = y.clone();
    qr.q_tr_mul(&mut qty);
    let r = qr.r();
    let svd = r.clone().svd(true, true);
    let sv = &svd.singular_values;
    let (smax, smin) = (sv.max(), sv.min());
    let condition = if smin > 0.0 {
        smax / smin
    } else {
        f64::INFINITY
    };
    if condition.is_nan() || condition > MAX_CONDITION {
        // The direction of the smallest singular value names the collinear columns.
        let vt = svd.v_t.as_ref().expect("invariant: V requested");
        let k = sv.imin();
        let row = vt.row(k);
        let big = row.amax();
        let names: Vec<&str> = terms
            .iter()
            .enumerate()
            .filter(|(j, _)| row[*j].abs() > 0.1 * big)
            .map(|(_, t)| t.label())
            .collect();
        return Err(BaselineError::Collinear {
            terms: names.join(", "),
            condition,
        });
    }
    let u = svd.u.as_ref().expect("invariant: U requested");
    let vt = svd.v_t.as_ref().expect("invariant: V requested");
    // R⁻¹ = V Σ⁻¹ Uᵀ.
    let mut v_sinv = vt.transpose();
    for (mut c, s) in v_sinv.column_iter_mut().zip(sv.iter()) {
        c /= *s;
    }
    let mut rinv = &v_sinv * u.transpose();
    let mut theta_s = &rinv * qty.rows(0, p);
    // Bias compensation: M = RᵀR − S D S; θₛ = M⁻¹ Rᵀ Qᵀ y. The sandwich below uses
    // `rinv` as the whitening `R⁻¹` of `M = RᵀR`; with the compensation the same formulas
    // hold with `R⁻¹ R⁻ᵀ` replaced by `M⁻¹`, i.e. `rinv` by `M⁻¹ Rᵀ`.
    let mut shift: Option<DVector<f64>> = None;
    // The sandwich `outer · Ω · outerᵀ` with scores whitened by `whiten`: `R⁻¹` and `R⁻ᵀ`
    // without compensation, `M⁻¹` and `I` with it.
    let mut outer: Option<DMatrix<f64>> = None;
    if let Some(d) = noise {
        let mut ds = d.clone();
        for i in 0..p {
            for j in 0..p {
                ds[(i, j)] *= scale[i] * scale[j];
            }
        }
        let m = r.transpose() * &r - &ds;
        if let Some(minv) = m.clone().try_inverse() {
            let b = r.transpose() * qty.rows(0, p);
            theta_s = &minv * b;
            rinv = &minv * r.transpose();
            shift = Some(&ds * &theta_s / n as f64);
            outer = Some(minv);
        }
    }
    let resid = &y - &xs * &theta_s;
    let ssr = resid.norm_squared();
    let dof = (n - p) as f64;
    let sigma2 = ssr / dof;
    let cov_ols = &rinv * rinv.transpose() * sigma2;
    // Scores whitened by R⁻ᵀ (one p-vector per row), then the Bartlett-weighted sum.
    let rinv_t = match outer {
        Some(_) => DMatrix::<f64>::identity(p, p),
        None => rinv.transpose(),
    };
    let mut g = &rinv_t * xs.transpose();
    for (mut c, e) in g.column_iter_mut().zip(resid.iter()) {
        c *= *e;
    }
    if let Some(sh) = &shift {
        // The compensation's share of each row's score, whitened like the rest.
        let add = &rinv_t * sh;
        for mut c in g.column_iter_mut() {
            c += &add;
        }
    }
    let mut omega = &g * g.transpose();
    let lag = hac_lag.min(n - 1);
    for l in 1..=lag {
        let w = 1.0 - l as f64 / (lag + 1) as f64;
        let a = g.columns(l, n - l);
        let b = g.columns(0, n - l);
        let gamma = a * b.transpose();
        omega += (&gamma + gamma.transpose()) * w;
    }
    let o = outer.as_ref().unwrap_or(&rinv);
    let cov_hac = o * omega * o.transpose() * (n as f64 / dof);
    let se = |cov: &DMatrix<f64>| -> Vec<f64> {
        (0..p)
            .map(|j| cov[(j, j)].max(0.0).sqrt() * scale[j])
            .collect()
    };
    Ok(Fit {
        terms: terms.to_vec(),
        estimates: theta_s.iter().zip(&scale).map(|(t, s)| t * s).collect(),
        stderr_ols: se(&cov_ols),
        stderr_hac: se(&cov_hac),
        hac_lag: lag,
        condition,
        rows: n,
        residual_rms: (ssr / n as f64).sqrt(),
    })
}
