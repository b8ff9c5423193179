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

use nalgebra::{DMatrix, DVector};

use super::candidate::{Candidate, Dependence, Distribution};
use super::{Estimate, Prediction, TemplateFit};

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

/// Intensities along a continuous path through the levels (sorted by σ_s, log-linear
/// between neighbours, extrapolated a little), for drawing template curves.
fn level_path(el: &ElementData, n: usize) -> Vec<(f64, f64)> {
    if el.sigma_s.is_empty() || n < 2 {
        return Vec::new();
    }
    let mut idx: Vec<usize> = (0..el.sigma_s.len()).collect();
    idx.sort_by(|&a, &b| el.sigma_s[a].total_cmp(&el.sigma_s[b]));
    let ls: Vec<f64> = idx.iter().map(|&i| el.sigma_s[i].ln()).collect();
    let lv: Vec<f64> = idx.iter().map(|&i| el.sigma_v[i].ln()).collect();
    let last = (idx.len() - 1) as f64;
    let (t0, t1) = (-0.15 * last.max(1.0), last + 0.15 * last.max(1.0));
    (0..n)
        .map(|i| {
            let t = t0 + (t1 - t0) * i as f64 / (n - 1) as f64;
            if idx.len() == 1 {
                return (ls[0].exp(), lv[0].exp());
            }
            let k = (t.floor().max(0.0) as usize).min(idx.len() - 2);
            let f = t - k as f64;
            let s = ls[k] + f * (ls[k + 1] - ls[k]);
            let v = lv[k] + f * (lv[k + 1] - lv[k]);
            (s.exp(), v.exp())
        })
        .collect()
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
    // shape: `fit.beta` and `fit.cov` have one entry per base and effect (the design's
    // columns), `joint` one more per shaped effect; `col` counts exactly those.
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
    let cov = joint.as_ref().unwrap_or(&fit.cov);
    let mut estimates = Vec::new();
    let mut col = 0;
    for c in [&el.stiffness, &el.damping].into_iter().flatten() {
        estimates.push(Estimate {
            name: format!("{} (linear part)", c.param),
            value: fit.beta[col],
            stderr: cov[(col, col)].sqrt() * inflate,
        });
        col += 1;
    }
    for e in effects {
        estimates.push(Estimate {
            name: e.coef_name.clone(),
            value: fit.beta[col],
            stderr: cov[(col, col)].sqrt() * inflate,
        });
        col += 1;
    }
    for &j in &shaped {
        let shape = effects[j].shape.as_ref().expect("invariant: shaped effect");
        let th = thetas[j];
        let se = match &joint {
            // Error of ln θ → error of θ.
            Some(cov) => th * cov[(col, col)].sqrt() * inflate,
            None => profile_stderr(el, effects, &thetas, j, fit.chi2) * inflate,
        };
        col += 1;
        estimates.push(Estimate {
            name: shape.name.clone(),
            value: th,
            stderr: se,
        });
    }
    // Smooth predictions for plots.
    let path = level_path(el, 80);
    let mut pk = Prediction {
        param: el
            .stiffness
            .as_ref()
            .map(|c| c.param.clone())
            .unwrap_or_default(),
        sigma: Vec::new(),
        value: Vec::new(),
    };
    let mut pd = Prediction {
        param: el
            .damping
            .as_ref()
            .map(|c| c.param.clone())
            .unwrap_or_default(),
        sigma: Vec::new(),
        value: Vec::new(),
    };
    let nb = el.n_bases();
    for &(ss, sv) in &path {
        let (mut yk, mut yd) = (0.0, 0.0);
        for (j, e) in effects.iter().enumerate() {
            let (hk, hd) = el.gains_at(e, ss, sv, thetas[j]);
            yk += fit.beta[nb + j] * hk;
            yd += fit.beta[nb + j] * hd;
        }
        pk.sigma.push(ss);
        pk.value.push(yk);
        pd.sigma.push(sv);
        pd.value.push(yd);
    }
    let mut predictions = Vec::new();
    let mut col = 0;
    if el.stiffness.is_some() {
        pk.value.iter_mut().for_each(|y| *y += fit.beta[col]);
        predictions.push(pk);
        col += 1;
    }
    if el.damping.is_some() {
        pd.value.iter_mut().for_each(|y| *y += fit.beta[col]);
        predictions.push(pd);
    }
    let explained = if chi2_const > 0.0 {
        1.0 - fit.chi2 / chi2_const
    } else {
        1.0
    };
    // Largest |correlation| between two effect coefficients: near 1 they trade off.
    let mut coef_corr: f64 = 0.0;
    for a in 0..effects.len() {
        for b in 0..a {
            let (i, j) = (nb + a, nb + b);
            let r = fit.cov[(i, j)] / (fit.cov[(i, i)] * fit.cov[(j, j)]).sqrt();
            coef_corr = coef_corr.max(r.abs());
        }
    }
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
