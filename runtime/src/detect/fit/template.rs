//! A fitted template as the detection reports it: its estimates with standard errors, the
//! predicted curves for plots, and how strongly its coefficients trade off.

use super::wls::LsFit;
use super::{profile_stderr, ElementData};
use crate::detect::candidate::Candidate;
use crate::detect::types::{Estimate, Prediction};
use nalgebra::DMatrix;

/// The estimates of a fitted template: the linear parts, the effects' coefficients and
/// their shapes, with standard errors from the joint covariance of (β, ln θ) where the
/// shapes are resolved (else the conditional ones, and θ's from the χ² profile), widened
/// by `inflate`.
pub(super) fn estimates(
    el: &ElementData,
    effects: &[&Candidate],
    thetas: &[f64],
    shaped: &[usize],
    fit: &LsFit,
    joint: Option<&DMatrix<f64>>,
    inflate: f64,
) -> Vec<Estimate> {
    // shape: `fit.beta` and `fit.cov` have one entry per base and effect (the design's
    // columns), `joint` one more per shaped effect; `col` counts exactly those.
    let cov = joint.unwrap_or(&fit.cov);
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
    for &j in shaped {
        let shape = effects[j].shape.as_ref().expect("invariant: shaped effect");
        let th = thetas[j];
        let se = match joint {
            // Error of ln θ → error of θ.
            Some(cov) => th * cov[(col, col)].sqrt() * inflate,
            None => profile_stderr(el, effects, thetas, j, fit.chi2) * inflate,
        };
        col += 1;
        estimates.push(Estimate {
            name: shape.name.clone(),
            value: th,
            stderr: se,
        });
    }
    estimates
}

/// Smooth predictions of the template's stiffness and damping curves along a path through
/// the levels, for plots.
pub(super) fn predictions(
    el: &ElementData,
    effects: &[&Candidate],
    thetas: &[f64],
    beta: &[f64],
) -> Vec<Prediction> {
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
            yk += beta[nb + j] * hk;
            yd += beta[nb + j] * hd;
        }
        pk.sigma.push(ss);
        pk.value.push(yk);
        pd.sigma.push(sv);
        pd.value.push(yd);
    }
    let mut predictions = Vec::new();
    let mut col = 0;
    if el.stiffness.is_some() {
        pk.value.iter_mut().for_each(|y| *y += beta[col]);
        predictions.push(pk);
        col += 1;
    }
    if el.damping.is_some() {
        pd.value.iter_mut().for_each(|y| *y += beta[col]);
        predictions.push(pd);
    }
    predictions
}

/// Largest |correlation| between two effect coefficients (columns `nb..nb + n_effects` of
/// `cov`): near 1 they trade off.
pub(super) fn coef_corr(cov: &DMatrix<f64>, nb: usize, n_effects: usize) -> f64 {
    // shape: `cov` is the covariance of the design's columns, `nb` bases then one per
    // effect, so `nb + n_effects` square.
    let mut coef_corr: f64 = 0.0;
    for a in 0..n_effects {
        for b in 0..a {
            let (i, j) = (nb + a, nb + b);
            let r = cov[(i, j)] / (cov[(i, i)] * cov[(j, j)]).sqrt();
            coef_corr = coef_corr.max(r.abs());
        }
    }
    coef_corr
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
