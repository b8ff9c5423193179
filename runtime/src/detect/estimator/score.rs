//! Scoring a trial against the measured curves: the drift it predicts at p (interpolated
//! between its runs) removed from every curve in scope, χ² about the constant, p fitted on
//! a fine grid with its standard error from the χ² profile, and the constancy test of the
//! corrected curves.

use super::runs::Trial;
use super::P_STEPS;
use crate::detect::constancy_test;
use crate::detect::fit::weighted_mean;
use crate::detect::types::{DetectOptions, ParamCurve, ParamCurveResult, Role};

/// The measured curves in the scope of one element: (param, element, values, stderrs used).
pub(super) struct Scoped<'a> {
    pub(super) curve: &'a ParamCurve,
    pub(super) se: &'a [f64],
}

/// Predicted drift of `param` at `p` (linear interpolation between the trial's runs) and
/// the standard error it adds: the simulated fits' own, times √(1 − n_sim/n) per level — a
/// simulated level as long as the measured one shares its input realisation and the
/// scatter cancels in the comparison; a short one does not.
pub(super) fn drift(t: &Trial, param: &str, p: f64, share: &[f64]) -> Option<(Vec<f64>, Vec<f64>)> {
    let get = |k: usize| -> Option<(&Vec<f64>, &Vec<f64>)> {
        t.curves[k]
            .iter()
            .find(|(n, _, _)| n == param)
            .map(|(_, v, e)| (v, e))
    };
    let (base, _) = get(0)?;
    // The runs' p are monotone (multiples 0 < f₁ < … of one estimate, of either sign):
    // find the interval that holds p and interpolate linearly within it.
    let n = t.ps.len() - 1;
    let (p0, plast) = (t.ps[0], t.ps[n]);
    let u = if plast != p0 {
        (p - p0) / (plast - p0)
    } else {
        0.0
    };
    let us: Vec<f64> =
        t.ps.iter()
            .map(|q| {
                if plast != p0 {
                    (q - p0) / (plast - p0)
                } else {
                    0.0
                }
            })
            .collect();
    let u = u.clamp(0.0, 1.0);
    let k = (0..n).find(|&k| u <= us[k + 1]).unwrap_or(n - 1);
    let f = if us[k + 1] > us[k] {
        ((u - us[k]) / (us[k + 1] - us[k])).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let ((a, ea), (b, eb)) = (get(k)?, get(k + 1)?);
    if base.len() != share.len() || a.len() != share.len() || b.len() != share.len() {
        return None;
    }
    Some(
        (0..base.len())
            .map(|l| {
                let d = (1.0 - f) * (a[l] - base[l]) + f * (b[l] - base[l]);
                let e = ((1.0 - f) * ea[l] + f * eb[l]) * (1.0 - share[l]).max(0.0).sqrt();
                (d, if e.is_finite() { e } else { 0.0 })
            })
            .unzip(),
    )
}

/// The curve with the predicted drift removed and the combined standard errors.
fn corrected_curve(c: &ParamCurve, se: &[f64], d: &[f64], e: &[f64]) -> ParamCurve {
    let mut c = c.clone();
    c.values.iter_mut().zip(d).for_each(|(y, d)| *y -= d);
    c.stderrs = se.iter().zip(e).map(|(a, b)| a.hypot(*b)).collect();
    c
}

/// χ² about the weighted mean of `y − Δ(p)`, summed over the scoped curves.
pub(super) fn chi2_at(t: &Trial, scope: &[Scoped], p: f64, share: &[f64]) -> f64 {
    let mut chi2 = 0.0;
    for s in scope {
        let Some((d, e)) = drift(t, &s.curve.param, p, share) else {
            return f64::INFINITY;
        };
        let c = corrected_curve(s.curve, s.se, &d, &e);
        let (m, _) = weighted_mean(&c.values, &c.stderrs);
        chi2 += c
            .values
            .iter()
            .zip(&c.stderrs)
            .map(|(y, e)| ((y - m) / e).powi(2))
            .sum::<f64>();
    }
    chi2
}

/// p of `t` fitted to the curves in `scope`: the least χ² on a grid of [`P_STEPS`] steps
/// over the trial's range, with its standard error from the χ² profile (half the width of
/// Δχ² ≤ 1, on the grid); `(p, stderr, χ²)`, or `None` where no χ² is finite.
pub(super) fn fit_p(t: &Trial, scope: &[Scoped], share: &[f64]) -> Option<(f64, f64, f64)> {
    let (lo, hi) = (
        t.ps[0].min(t.ps[t.ps.len() - 1]),
        t.ps[0].max(t.ps[t.ps.len() - 1]),
    );
    let grid: Vec<f64> = (0..=P_STEPS)
        .map(|i| lo + (hi - lo) * i as f64 / P_STEPS as f64)
        .collect();
    let chis: Vec<f64> = grid.iter().map(|&p| chi2_at(t, scope, p, share)).collect();
    let best = (0..grid.len()).min_by(|&i, &j| chis[i].total_cmp(&chis[j]))?;
    if !chis[best].is_finite() {
        return None;
    }
    let p = grid[best];
    // Standard error from the χ² profile (Δχ² = 1), on the fine grid.
    let within: Vec<f64> = grid
        .iter()
        .zip(&chis)
        .filter(|(_, c)| **c <= chis[best] + 1.0)
        .map(|(g, _)| *g)
        .collect();
    let step = (hi - lo) / P_STEPS as f64;
    let half = 0.5
        * (within.iter().copied().fold(f64::NEG_INFINITY, f64::max)
            - within.iter().copied().fold(f64::INFINITY, f64::min)
            + step);
    Some((p, half, chis[best]))
}

/// The curves of `element` (stiffness and damping, of `params`) that still drift by the
/// constancy test once `t`'s drift at `p` is removed, and whether the trial predicts a
/// drift for every one of them.
pub(super) fn still_drifting(
    params: &[ParamCurveResult],
    element: &str,
    t: &Trial,
    p: f64,
    share: &[f64],
    opts: &DetectOptions,
) -> (Vec<String>, bool) {
    let mut left = Vec::new();
    let mut ok = true;
    for r in params.iter().filter(|r| {
        r.curve.element == element && matches!(r.curve.role, Role::Stiffness | Role::Damping)
    }) {
        let Some((d, e)) = drift(t, &r.curve.param, p, share) else {
            ok = false;
            continue;
        };
        // The stderrs the measured test used (floored) with the prediction's.
        let c = corrected_curve(&r.curve, &r.stderrs_used, &d, &e);
        if constancy_test(&c, r.sigma.clone(), &r.sigma_name, opts).drifting {
            left.push(r.curve.param.clone());
        }
    }
    (left, ok)
}
