//! Weighted least-squares fits of the constant model and of effect templates to an
//! element's stiffness and damping curves.
//!
//! A template is a set of effects sharing one coefficient each across both curves:
//!
//! ```text
//! k_eq(l) = k + Σ_j p_j h_k,j(σ_s,l, σ_v,l; θ_j)      d_eq(l) = d + Σ_j p_j h_d,j(…)
//! ```
//!
//! k, d and p enter linearly (solved by SVD of the whitened design, never the normal
//! equations); a shape parameter θ_j by a log-grid search refined by golden section.
//!
//! This module fits; `wls` solves the weighted least squares, `template` turns a fit into
//! the reported estimates and curves.

use nalgebra::{DMatrix, DVector};

use super::candidate::{Candidate, Dependence, Distribution};
use super::types::TemplateFit;

mod template;
mod wls;

use template::{coef_corr, estimates, predictions};
pub(crate) use wls::{aicc, weighted_ls, weighted_mean, LsFit};

/// One curve of an element as the fit sees it.
#[derive(Clone, Debug)]
pub(crate) struct CurveData {
    pub param: String,
    pub y: Vec<f64>,
    pub se: Vec<f64>,
}

/// The element's curves and intensities at every level.
#[derive(Clone, Debug)]
pub(crate) struct ElementData {
    pub stiffness: Option<CurveData>,
    pub damping: Option<CurveData>,
    pub sigma_s: Vec<f64>,
    pub sigma_v: Vec<f64>,
    /// Measured distributions per level, or empty (Gaussian gains).
    pub s_dist: Vec<Distribution>,
    pub v_dist: Vec<Distribution>,
}

impl ElementData {
    pub fn n_points(&self) -> usize {
        self.stiffness.as_ref().map_or(0, |c| c.y.len())
            + self.damping.as_ref().map_or(0, |c| c.y.len())
    }
    /// The gains of an effect at level `l`.
    pub fn gains(&self, c: &Candidate, l: usize, theta: f64) -> (f64, f64) {
        c.gains_with(
            self.sigma_s[l],
            self.sigma_v[l],
            theta,
            self.s_dist.get(l),
            self.v_dist.get(l),
        )
    }

    /// The gains along the plotting path at (σ_s, σ_v): the Gaussian gain times the ratio
    /// measured/Gaussian interpolated in ln σ_s between the levels (held beyond them), so
    /// that the curve is smooth and passes through the fitted value at each level.
    fn gains_at(&self, c: &Candidate, ss: f64, sv: f64, theta: f64) -> (f64, f64) {
        let g = c.gains(ss, sv, theta);
        if self.s_dist.is_empty() && self.v_dist.is_empty() {
            return g;
        }
        let ratio = |m: f64, g: f64| {
            if g != 0.0 && m.is_finite() {
                m / g
            } else {
                1.0
            }
        };
        let mut pts: Vec<(f64, f64, f64)> = (0..self.sigma_s.len())
            .map(|l| {
                let m = self.gains(c, l, theta);
                let g = c.gains(self.sigma_s[l], self.sigma_v[l], theta);
                (self.sigma_s[l].ln(), ratio(m.0, g.0), ratio(m.1, g.1))
            })
            .collect();
        if pts.is_empty() {
            return g;
        }
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        let x = ss.ln();
        let k = pts.iter().position(|p| p.0 >= x).unwrap_or(pts.len());
        let (rk, rd) = if k == 0 {
            (pts[0].1, pts[0].2)
        } else if k == pts.len() {
            (pts[k - 1].1, pts[k - 1].2)
        } else {
            let (a, b) = (pts[k - 1], pts[k]);
            let f = if b.0 > a.0 {
                (x - a.0) / (b.0 - a.0)
            } else {
                0.0
            };
            (a.1 + f * (b.1 - a.1), a.2 + f * (b.2 - a.2))
        };
        (g.0 * rk, g.1 * rd)
    }

    pub(crate) fn n_bases(&self) -> usize {
        usize::from(self.stiffness.is_some()) + usize::from(self.damping.is_some())
    }
}

/// Rows of the template design at given shapes: bases first, then one column per effect.
fn design(
    el: &ElementData,
    effects: &[&Candidate],
    thetas: &[f64],
) -> (DMatrix<f64>, Vec<f64>, Vec<f64>) {
    let nb = el.n_bases();
    let m = nb + effects.len();
    let n = el.n_points();
    let mut a = DMatrix::zeros(n, m);
    // shape: `a` is `n_points × (bases + effects)`; each curve present fills one row per
    // level, and `detect` checks that every curve has one value per level
    // (`DetectError::Length`), so `row < n_points` and `j < effects`.
    let mut y = Vec::with_capacity(n);
    let mut se = Vec::with_capacity(n);
    let levels = el.sigma_s.len();
    let gains: Vec<Vec<(f64, f64)>> = (0..levels)
        .map(|l| {
            effects
                .iter()
                .zip(thetas)
                .map(|(c, &t)| el.gains(c, l, t))
                .collect()
        })
        .collect();
    let mut row = 0;
    let mut base = 0;
    if let Some(k) = &el.stiffness {
        for (l, gl) in gains.iter().enumerate() {
            a[(row, base)] = 1.0;
            for (j, g) in gl.iter().enumerate() {
                a[(row, nb + j)] = g.0;
            }
            y.push(k.y[l]);
            se.push(k.se[l]);
            row += 1;
        }
        base += 1;
    }
    if let Some(d) = &el.damping {
        for (l, gl) in gains.iter().enumerate() {
            a[(row, base)] = 1.0;
            for (j, g) in gl.iter().enumerate() {
                a[(row, nb + j)] = g.1;
            }
            y.push(d.y[l]);
            se.push(d.se[l]);
            row += 1;
        }
    }
    (a, y, se)
}

fn solve(el: &ElementData, effects: &[&Candidate], thetas: &[f64]) -> Option<LsFit> {
    let (a, y, se) = design(el, effects, thetas);
    // An effect with no gain on the curves present cannot be told from zero.
    let nb = el.n_bases();
    for j in nb..a.ncols() {
        let col_max = a.column(j).amax();
        if col_max.is_nan() || col_max <= 1e-300 || !col_max.is_finite() {
            return None;
        }
    }
    let fit = weighted_ls(&a, &y, &se)?;
    // A sign-constrained effect fitted negative reduces the template to a smaller one that
    // is ranked on its own; treating it as infeasible also keeps shape searches physical.
    if effects
        .iter()
        .enumerate()
        .any(|(j, e)| e.positive && fit.beta[nb + j] < 0.0)
    {
        return None;
    }
    Some(fit)
}

fn chi2_at(el: &ElementData, effects: &[&Candidate], thetas: &[f64]) -> f64 {
    solve(el, effects, thetas).map_or(f64::INFINITY, |f| f.chi2)
}

fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n == 0 {
        return f64::NAN;
    }
    if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}

const GRID: usize = 48;
const GOLDEN_ITERS: usize = 60;

/// Minimise χ² over θ_j (others fixed) on a log grid, refined by golden section.
fn search_shape(el: &ElementData, effects: &[&Candidate], thetas: &mut [f64], j: usize) {
    let shape = effects[j].shape.as_ref().expect("invariant: shaped effect");
    let sig = match shape.scale_by {
        Dependence::V => median(&el.sigma_v),
        _ => median(&el.sigma_s),
    };
    let (lo, hi) = ((shape.lo_rel * sig).ln(), (shape.hi_rel * sig).ln());
    let eval = |u: f64, th: &mut [f64]| {
        th[j] = u.exp();
        chi2_at(el, effects, th)
    };
    let mut work = thetas.to_vec();
    let grid: Vec<f64> = (0..GRID)
        .map(|i| lo + (hi - lo) * i as f64 / (GRID - 1) as f64)
        .collect();
    let vals: Vec<f64> = grid.iter().map(|&u| eval(u, &mut work)).collect();
    // shape: `best` and its neighbours are clamped to `0..GRID`.
    let best = (0..GRID)
        .min_by(|&a, &b| vals[a].total_cmp(&vals[b]))
        .unwrap_or(0);
    let (mut a, mut b) = (grid[best.saturating_sub(1)], grid[(best + 1).min(GRID - 1)]);
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let mut c = b - g * (b - a);
    let mut d = a + g * (b - a);
    let mut fc = eval(c, &mut work);
    let mut fd = eval(d, &mut work);
    for _ in 0..GOLDEN_ITERS {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - g * (b - a);
            fc = eval(c, &mut work);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + g * (b - a);
            fd = eval(d, &mut work);
        }
    }
    let u_ref = 0.5 * (a + b);
    let f_ref = eval(u_ref, &mut work);
    thetas[j] = if f_ref <= vals[best] {
        u_ref.exp()
    } else {
        grid[best].exp()
    };
}

/// The constant model (one base per curve): χ², number of parameters.
pub(crate) fn constant_chi2(el: &ElementData) -> (f64, usize) {
    let mut chi2 = 0.0;
    for c in [&el.stiffness, &el.damping].into_iter().flatten() {
        let (mean, _) = weighted_mean(&c.y, &c.se);
        chi2 +=
            c.y.iter()
                .zip(&c.se)
                .map(|(y, s)| ((y - mean) / s).powi(2))
                .sum::<f64>();
    }
    (chi2, el.n_bases())
}

/// Standard error of θ_j from the curvature of the χ² profile in ln θ (Δχ² = 1 at one
/// standard error); NaN where the profile is flat or not convex.
fn profile_stderr(
    el: &ElementData,
    effects: &[&Candidate],
    thetas: &[f64],
    j: usize,
    chi2: f64,
) -> f64 {
    let h: f64 = 0.02;
    let th = thetas[j];
    let mut t = thetas.to_vec();
    t[j] = th * h.exp();
    let fp = chi2_at(el, effects, &t);
    t[j] = th * (-h).exp();
    let fm = chi2_at(el, effects, &t);
    let curv = (fp - 2.0 * chi2 + fm) / (h * h);
    if curv > 0.0 && curv.is_finite() {
        th * (2.0 / curv).sqrt()
    } else {
        f64::NAN
    }
}

/// Covariance of (β, ln θ_shaped) at the optimum: the weighted design augmented by one
/// column per shape, ∂(A(θ) β)/∂ln θ_j (central difference), solved by SVD. `None` when
/// there is no shape or the augmented design is rank-deficient.
fn joint_covariance(
    el: &ElementData,
    effects: &[&Candidate],
    thetas: &[f64],
    shaped: &[usize],
    beta: &[f64],
) -> Option<DMatrix<f64>> {
    if shaped.is_empty() {
        return None;
    }
    let (a, y, se) = design(el, effects, thetas);
    let (n, m) = a.shape();
    let mut aug = a.clone().resize_horizontally(m + shaped.len(), 0.0);
    // shape: `aug` has the `n` rows of the design and `m + shaped` columns; `plus` and
    // `minus` are designs of the same `n` rows times `beta` (length `m`, the fit's).
    let h: f64 = 1e-3;
    let b = DVector::from_column_slice(beta);
    for (k, &j) in shaped.iter().enumerate() {
        let mut t = thetas.to_vec();
        t[j] = thetas[j] * h.exp();
        let plus = design(el, effects, &t).0 * &b;
        t[j] = thetas[j] * (-h).exp();
        let minus = design(el, effects, &t).0 * &b;
        for i in 0..n {
            aug[(i, m + k)] = (plus[i] - minus[i]) / (2.0 * h);
        }
    }
    weighted_ls(&aug, &y, &se).map(|f| f.cov)
}

/// Fit one template (a set of effects) and score it; `None` when it does not apply to
/// this element's curves (no gain on any curve present, or unidentifiable).
pub(crate) fn fit_template(
    el: &ElementData,
    effects: &[&Candidate],
    chi2_const: f64,
) -> Option<TemplateFit> {
    let mut thetas: Vec<f64> = vec![0.0; effects.len()];
    let shaped: Vec<usize> = (0..effects.len())
        .filter(|&j| effects[j].shape.is_some())
        .collect();
    let sweeps = if shaped.len() > 1 { 3 } else { 1 };
    for _ in 0..sweeps {
        for &j in &shaped {
            search_shape(el, effects, &mut thetas, j);
        }
    }
    let fit = solve(el, effects, &thetas)?;
    let n = el.n_points();
    let k_params = el.n_bases() + effects.len() + shaped.len();
    let dof = n.saturating_sub(k_params);
    let reduced = if dof > 0 {
        fit.chi2 / dof as f64
    } else {
        f64::NAN
    };
    // Stated errors assume the row errors are right; when the template leaves more scatter
    // than they allow, widen by √(χ²/dof) rather than pretend a precision the fit lacks.
    let inflate = if reduced.is_finite() {
        reduced.max(1.0).sqrt()
    } else {
        1.0
    };
    // Errors of the linear coefficients at a fixed shape would ignore how they trade off
    // against it (a backlash's kb against its gap); the Gauss–Newton covariance of
    // (β, ln θ) at the optimum includes that. Where θ is not resolved (rank-deficient
    // augmented design) the conditional errors stand and θ's error comes from the χ² profile.
    let joint = joint_covariance(el, effects, &thetas, &shaped, &fit.beta);
    let estimates = estimates(el, effects, &thetas, &shaped, &fit, joint.as_ref(), inflate);
    let predictions = predictions(el, effects, &thetas, &fit.beta);
    let nb = el.n_bases();
    let explained = if chi2_const > 0.0 {
        1.0 - fit.chi2 / chi2_const
    } else {
        1.0
    };
    let coef_corr = coef_corr(&fit.cov, nb, effects.len());
    Some(TemplateFit {
        coef_corr,
        name: effects
            .iter()
            .map(|e| e.name.as_str())
            .collect::<Vec<_>>()
            .join(" + "),
        effects: effects.iter().map(|e| e.name.clone()).collect(),
        formula: effects
            .iter()
            .map(|e| e.formula.as_str())
            .collect::<Vec<_>>()
            .join(" + "),
        estimates,
        n_effect_estimates: effects.len() + shaped.len(),
        chi2: fit.chi2,
        dof,
        n_params: k_params,
        n_points: n,
        reduced_chi2: reduced,
        gof_p_value: if dof > 0 {
            super::stats::chi2_sf(fit.chi2, dof as f64)
        } else {
            f64::NAN
        },
        explained,
        aicc: aicc(fit.chi2, k_params, n),
        bic: fit.chi2 + k_params as f64 * (n as f64).ln(),
        delta_aicc: 0.0,
        cond: fit.cond,
        inverse_pair: false,
        predictions,
    })
}
